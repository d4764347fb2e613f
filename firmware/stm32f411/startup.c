/* Reset and the vector table of the STM32F411: copy .data, clear .bss, FPU on, then main.
 * Written here because no vendor startup (CMSIS) is in Debian's packages; the firmware is
 * polled, so every interrupt but the faults is left off and its vector points at a trap. */
#include <stdint.h>

extern uint32_t _stack_top, _data_load, _data_start, _data_end, _bss_start, _bss_end;
int main(void);

void reset_handler(void);
void trap_handler(void);

void trap_handler(void)
{
    for (;;) {
    }
}

void reset_handler(void)
{
    const uint32_t *from = &_data_load;
    for (uint32_t *to = &_data_start; to < &_data_end;) {
        *to++ = *from++;
    }
    for (uint32_t *to = &_bss_start; to < &_bss_end;) {
        *to++ = 0;
    }
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20; /* CPACR: CP10, CP11 full access */
    __asm volatile("dsb\n isb");
    main();
    for (;;) {
    }
}

/* 16 system vectors + 86 peripheral interrupts (RM0383 table 37). */
__attribute__((section(".vectors"), used)) static void (*const vectors[16 + 86])(void) = {
    [0] = (void (*)(void))&_stack_top,
    [1] = reset_handler,
    [2 ... 16 + 85] = trap_handler,
};

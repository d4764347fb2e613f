/* The STM32F411 registers this firmware touches (RM0383), by address: no vendor headers. */
#ifndef IRDAQ_STM32F411_REGS_H
#define IRDAQ_STM32F411_REGS_H

#include <stdint.h>

#define REG(address) (*(volatile uint32_t *)(address))

#define RCC 0x40023800u
#define RCC_CR REG(RCC + 0x00u)
#define RCC_PLLCFGR REG(RCC + 0x04u)
#define RCC_CFGR REG(RCC + 0x08u)
#define RCC_AHB1ENR REG(RCC + 0x30u)
#define RCC_AHB2ENR REG(RCC + 0x34u)
#define RCC_APB1ENR REG(RCC + 0x40u)
#define RCC_APB2ENR REG(RCC + 0x44u)
#define FLASH_ACR REG(0x40023C00u)

#define GPIOA 0x40020000u
#define GPIOA_MODER REG(GPIOA + 0x00u)
#define GPIOA_OSPEEDR REG(GPIOA + 0x08u)
#define GPIOA_AFRH REG(GPIOA + 0x24u)

#define TIM2 0x40000000u
#define TIM2_CR1 REG(TIM2 + 0x00u)
#define TIM2_CR2 REG(TIM2 + 0x04u)
#define TIM2_EGR REG(TIM2 + 0x14u)
#define TIM2_CNT REG(TIM2 + 0x24u)
#define TIM2_PSC REG(TIM2 + 0x28u)
#define TIM2_ARR REG(TIM2 + 0x2Cu)

#define ADC1 0x40012000u
#define ADC1_SR REG(ADC1 + 0x00u)
#define ADC1_CR1 REG(ADC1 + 0x04u)
#define ADC1_CR2 REG(ADC1 + 0x08u)
#define ADC1_SMPR2 REG(ADC1 + 0x10u)
#define ADC1_SQR1 REG(ADC1 + 0x2Cu)
#define ADC1_SQR3 REG(ADC1 + 0x34u)
#define ADC1_DR_ADDRESS (ADC1 + 0x4Cu)
#define ADC_CCR REG(0x40012304u)

#define DMA2 0x40026400u
#define DMA2_LISR REG(DMA2 + 0x00u)
#define DMA2_LIFCR REG(DMA2 + 0x08u)
#define DMA2_S0CR REG(DMA2 + 0x10u)
#define DMA2_S0NDTR REG(DMA2 + 0x14u)
#define DMA2_S0PAR REG(DMA2 + 0x18u)
#define DMA2_S0M0AR REG(DMA2 + 0x1Cu)

#define OTG 0x50000000u
#define OTG_GAHBCFG REG(OTG + 0x008u)
#define OTG_GUSBCFG REG(OTG + 0x00Cu)
#define OTG_GRSTCTL REG(OTG + 0x010u)
#define OTG_GINTSTS REG(OTG + 0x014u)
#define OTG_GINTMSK REG(OTG + 0x018u)
#define OTG_GRXSTSP REG(OTG + 0x020u)
#define OTG_GRXFSIZ REG(OTG + 0x024u)
#define OTG_DIEPTXF0 REG(OTG + 0x028u)
#define OTG_GCCFG REG(OTG + 0x038u)
#define OTG_DIEPTXF(n) REG(OTG + 0x104u + 4u * ((n) - 1u))
#define OTG_DCFG REG(OTG + 0x800u)
#define OTG_DCTL REG(OTG + 0x804u)
#define OTG_DIEPMSK REG(OTG + 0x810u)
#define OTG_DOEPMSK REG(OTG + 0x814u)
#define OTG_DAINTMSK REG(OTG + 0x81Cu)
#define OTG_DIEPCTL(n) REG(OTG + 0x900u + 0x20u * (n))
#define OTG_DIEPINT(n) REG(OTG + 0x908u + 0x20u * (n))
#define OTG_DIEPTSIZ(n) REG(OTG + 0x910u + 0x20u * (n))
#define OTG_DTXFSTS(n) REG(OTG + 0x918u + 0x20u * (n))
#define OTG_DOEPCTL(n) REG(OTG + 0xB00u + 0x20u * (n))
#define OTG_DOEPINT(n) REG(OTG + 0xB08u + 0x20u * (n))
#define OTG_DOEPTSIZ(n) REG(OTG + 0xB10u + 0x20u * (n))
#define OTG_PCGCCTL REG(OTG + 0xE00u)
#define OTG_FIFO(n) REG(OTG + 0x1000u + 0x1000u * (n))

#endif

#!/usr/bin/env bash
# Build the IRDAQ-4 firmware for the STM32F411CE ("Black Pill") with Debian's
# gcc-arm-none-eabi and newlib: prints the image's section sizes and the .bin's size.
#   firmware/build_target.sh [OUT_DIR]     (default: a new temporary directory)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$(mktemp -d)}
mkdir -p "$out"
flags=(-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -std=c11 -O2
       -Wall -Wextra -Werror -ffunction-sections -fdata-sections)
arm-none-eabi-gcc "${flags[@]}" -nostartfiles --specs=nano.specs --specs=nosys.specs \
  -T "$here/stm32f411/stm32f411.ld" -Wl,--gc-sections -Wl,-u,_printf_float \
  -o "$out/irdaq-f411.elf" "$here"/core/*.c "$here"/stm32f411/*.c -lm
arm-none-eabi-objcopy -O binary "$out/irdaq-f411.elf" "$out/irdaq-f411.bin"
arm-none-eabi-size "$out/irdaq-f411.elf"
echo "firmware image $out/irdaq-f411.bin: $(stat -c %s "$out/irdaq-f411.bin") bytes"

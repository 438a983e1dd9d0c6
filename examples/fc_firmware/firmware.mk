# examples/fc_firmware/firmware.mk: libdan inside flight-controller firmware.
# Included from the top-level Makefile (needs its BUILD, WARN, INCLUDES,
# GW_CLIENT_SRC, PORTABLE_SRC and ensure_debs);
# standalone: make -f Makefile -f examples/fc_firmware/firmware.mk firmware
#
#   make firmware      build/fw/fc_firmware.elf (Cortex-M4, QEMU mps2-an386)
#   make run-firmware  run it under QEMU on FW_SERIAL (a pty path; see below)
#   make size          flash/RAM of libdan's FC parts at -Os for Cortex-M4;
#                      fails over FW_FLASH_BUDGET / FW_RAM_BUDGET
#   make portability   the portable sources, -std=c99 -pedantic -Werror, with
#                      arm-none-eabi-gcc, clang and (if it installs)
#                      riscv64-unknown-elf-gcc
#   make deps-firmware install the Debian packages these need

# Included anywhere, it leaves the Makefile's default goal alone.
FW_SAVED_GOAL := $(.DEFAULT_GOAL)
BUILD  ?= build
PYTHON ?= python3

FW_DIR    := examples/fc_firmware
FW_BUILD  := $(BUILD)/fw
FW_ELF    := $(FW_BUILD)/fc_firmware.elf
FW_CC     := arm-none-eabi-gcc
FW_NM     := arm-none-eabi-nm
FW_SIZE   := arm-none-eabi-size
FW_ARCH   := -mcpu=cortex-m4 -mthumb
# The budget README.md states (see "Size budget" there).
FW_FLASH_BUDGET ?= 8166
FW_RAM_BUDGET   ?= 1056
# Worst-case stack of any public call (-fcallgraph-info=su, summed along the calls).
FW_STACK_BUDGET ?= 244

DEBS_FW   := gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi qemu-system-arm clang
DEBS_RV   := gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf

# What an FC links to drive ESCs through the CAN gateway: its client.
FW_GW_SRC := $(GW_CLIENT_SRC) src/crc16.c

FW_CFLAGS  = $(FW_ARCH) -Os -g $(WARN) -ffunction-sections -fdata-sections \
             -fcallgraph-info=su $(INCLUDES) -I$(FW_DIR) -MMD -MP
FW_LDFLAGS = $(FW_ARCH) --specs=nano.specs -nostartfiles -Wl,--gc-sections \
             -T $(FW_DIR)/fc_firmware.ld

FW_CODEC_SRC  := src/common.c src/crc8.c src/frame.c src/payloads.c
FW_MASTER_SRC := src/link.c src/master.c src/master_seq.c
FW_LIB_SRC    := $(FW_CODEC_SRC) $(FW_MASTER_SRC) src/types.c src/rxring.c src/identity_json.c \
                 $(FW_GW_SRC)
FW_APP_SRC    := $(FW_DIR)/startup.c $(FW_DIR)/board.c $(FW_DIR)/main.c $(FW_DIR)/fw_out.c \
                 $(FW_DIR)/twobus.c

fw_obj = $(patsubst %.c,$(FW_BUILD)/obj/%.o,$(1))
FW_OBJS     := $(call fw_obj,$(FW_LIB_SRC) $(FW_APP_SRC))
FW_GW_OBJS  := $(call fw_obj,$(FW_GW_SRC))
FW_SIZE_OBJS = $(call fw_obj,$(FW_CODEC_SRC) $(FW_MASTER_SRC))

# Portable sources (PORTABLE_SRC, from the Makefile): -pedantic on top.
PORT_WARN    := $(WARN) -pedantic $(INCLUDES)

.PHONY: firmware run-firmware size portability deps-firmware

deps-firmware:
	$(call ensure_debs,$(DEBS_FW))

firmware: $(FW_ELF)

# The flags in a stamp file: objects rebuild when they change.
$(FW_BUILD)/flags: FORCE_FW_FLAGS
	@mkdir -p $(@D)
	@echo '$(FW_CFLAGS)' | cmp -s - $@ || echo '$(FW_CFLAGS)' > $@
.PHONY: FORCE_FW_FLAGS

$(FW_BUILD)/obj/%.o: %.c $(FW_BUILD)/flags | deps-firmware
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -c $< -o $@

$(FW_ELF): $(FW_OBJS) $(FW_DIR)/fc_firmware.ld
	$(FW_CC) $(FW_LDFLAGS) -Wl,-Map=$(FW_BUILD)/fc_firmware.map $(FW_OBJS) -o $@
	@$(FW_SIZE) $@

-include $(shell find $(FW_BUILD) -name '*.d' 2>/dev/null)

# QEMU needs the host to own the pty (README.md, "QEMU facts"): give it a
# dan-vbus endpoint, e.g. FW_SERIAL=$$(readlink -f /tmp/dan0).
FW_SERIAL ?=
FW_APPEND ?=
run-firmware: $(FW_ELF)
	@test -n "$(FW_SERIAL)" || { echo "usage: make run-firmware FW_SERIAL=/dev/pts/N [FW_APPEND='gw=off']" >&2; exit 2; }
	qemu-system-arm -M mps2-an386 -display none -monitor none \
	  -semihosting-config enable=on,target=native -kernel $(FW_ELF) -serial $(FW_SERIAL) \
	  $(if $(FW_APPEND),-append '$(FW_APPEND)')

# ---- size --------------------------------------------------------------------
# Minimal images: SIZE_PROBE=0 (vector table only), 1 (+ master engine and
# codec), 2 (+ the gateway calls an FC makes), 3 (+ the whole gateway API).
# The report sums the input sections the linker kept per object (map file).

FW_PROBES := 0 1 2 3
FW_PROBE_TOP := 2

$(FW_BUILD)/size/probe%.o: $(FW_DIR)/size_probe.c $(FW_BUILD)/flags | deps-firmware
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -DSIZE_PROBE=$* -c $< -o $@

$(FW_BUILD)/size/probe%.elf: $(FW_BUILD)/size/probe%.o $(FW_SIZE_OBJS) $(FW_GW_OBJS)
	$(FW_CC) $(FW_LDFLAGS) -Wl,-Map=$(FW_BUILD)/size/probe$*.map $^ -o $@

# The FC image again with the 16-byte nibble crc8 table (DAN_CRC8_TABLE=0).
FW_CRC_NIBBLE := $(FW_BUILD)/size/crc8_nibble.o
$(FW_CRC_NIBBLE): src/crc8.c $(FW_BUILD)/flags | deps-firmware
	@mkdir -p $(@D)
	$(FW_CC) $(FW_CFLAGS) -DDAN_CRC8_TABLE=0 -c $< -o $@
$(FW_BUILD)/size/probe$(FW_PROBE_TOP)n.elf: $(FW_BUILD)/size/probe$(FW_PROBE_TOP).o $(FW_CRC_NIBBLE) \
                                          $(filter-out %/crc8.o,$(FW_SIZE_OBJS)) $(FW_GW_OBJS)
	$(FW_CC) $(FW_LDFLAGS) -Wl,-Map=$(FW_BUILD)/size/probe$(FW_PROBE_TOP)n.map $^ -o $@

size: $(foreach p,$(FW_PROBES),$(FW_BUILD)/size/probe$(p).elf) $(FW_BUILD)/size/probe$(FW_PROBE_TOP)n.elf
	@$(FW_SIZE) $(foreach p,$(FW_PROBES),$(FW_BUILD)/size/probe$(p).elf)
	@$(PYTHON) $(FW_DIR)/size_report.py --nm $(FW_NM) --objdump arm-none-eabi-objdump \
	  --ci-dir $(FW_BUILD)/obj --stack-budget $(FW_STACK_BUDGET) \
	  --base $(FW_BUILD)/size/probe0.map --image $(FW_BUILD)/size/probe$(FW_PROBE_TOP).map \
	  --elf $(FW_BUILD)/size/probe$(FW_PROBE_TOP).elf \
	  --full $(FW_BUILD)/size/probe3.map --nibble $(FW_BUILD)/size/probe$(FW_PROBE_TOP)n.map \
	  --flash-budget $(FW_FLASH_BUDGET) --ram-budget $(FW_RAM_BUDGET)

# ---- portability ---------------------------------------------------------------

portability: deps-firmware
	-$(call ensure_debs,$(DEBS_RV))
	@mkdir -p $(FW_BUILD)/port
	@set -e; for f in $(PORTABLE_SRC); do \
	  o=$(FW_BUILD)/port/$$(basename $$f .c); \
	  $(FW_CC) $(FW_ARCH) -Os $(PORT_WARN) -c $$f -o $$o.arm.o; \
	  clang $(PORT_WARN) -c $$f -o $$o.clang.o; \
	done; echo "portability: arm-none-eabi-gcc ok, clang ok ($(words $(PORTABLE_SRC)) files)"
	@if command -v riscv64-unknown-elf-gcc >/dev/null 2>&1; then \
	  set -e; for f in $(PORTABLE_SRC); do \
	    riscv64-unknown-elf-gcc --specs=picolibc.specs -march=rv32imac -mabi=ilp32 -Os $(PORT_WARN) \
	      -c $$f -o $(FW_BUILD)/port/$$(basename $$f .c).rv.o; \
	  done; echo "portability: riscv64-unknown-elf-gcc (rv32imac) ok"; \
	else echo "portability: riscv64-unknown-elf-gcc not installed: skipped"; fi

# Keep the probe objects (pattern-rule intermediates) between runs.
.SECONDARY: $(foreach p,0 1 2 3,$(FW_BUILD)/size/probe$(p).o)

.DEFAULT_GOAL := $(FW_SAVED_GOAL)

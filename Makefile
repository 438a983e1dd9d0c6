# DAN: libdan, the CAN-over-DAN gateway, tools and tests.
#
#   make            build libdan, the POSIX port, the tools and the gateway
#   make test       install test dependencies, run C unit tests (plain and
#                   ASan+UBSan) and the Python end-to-end tests
#   make cross      compile src/ for Cortex-M4 and print section sizes
#   make install    PREFIX=/usr/local DESTDIR= ; headers, libdan.a, dan.pc
#
# Missing Debian packages are installed with apt-get (sudo when not root).

BUILD   ?= build
PREFIX  ?= /usr/local
DESTDIR ?=
CC      ?= cc
AR      ?= ar
PYTHON  ?= python3
VENV    := .venv
VERSION := 0.1.0

WARN     := -std=c99 -Wall -Wextra -Werror -Wconversion -Wshadow
OPT      ?= -O2 -g
SAN      ?=
ifeq ($(SAN),1)
OPT      := -O1 -g -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
LDSAN    := -fsanitize=address,undefined
endif
CFLAGS_ALL  = $(WARN) $(OPT) -Iinclude -MMD -MP $(EXTRA_CFLAGS)
# POSIX code (ports, tools, daemons) may use POSIX and Linux interfaces.
CFLAGS_POSIX = $(CFLAGS_ALL) -D_GNU_SOURCE

# libgpiod (v1 API) drives a direction pin; built only when present.
HAVE_GPIOD := $(shell pkg-config --exists libgpiod 2>/dev/null && echo 1)
ifeq ($(HAVE_GPIOD),1)
GPIOD_CFLAGS := -DDAN_HAVE_GPIOD $(shell pkg-config --cflags libgpiod)
GPIOD_LIBS   := $(shell pkg-config --libs libgpiod)
endif

LIB_SRC   := $(wildcard src/*.c)
PORT_SRC  := $(wildcard src/port/*.c)
GW_SRC    := $(wildcard peripherals/can_gateway/*.c)
GWD_MAIN  := $(wildcard peripherals/can_gateway/linux/dan-gatewayd.c)
GWL_SRC   := $(filter-out $(GWD_MAIN),$(wildcard peripherals/can_gateway/linux/*.c))
TOOL_SRC  := $(wildcard host_tools/c/*.c)
TTOOL_SRC := $(wildcard tests/tools/*.c)
UNIT_SRC  := $(wildcard tests/unit/test_*.c)
UNIT_HELP := $(filter-out $(UNIT_SRC),$(wildcard tests/unit/*.c))

obj = $(patsubst %.c,$(BUILD)/obj/%.o,$(1))

LIB      := $(BUILD)/libdan.a
LIBPOSIX := $(BUILD)/libdan_posix.a
LIBGW    := $(BUILD)/libdan_gateway.a
LIBGWL   := $(BUILD)/libdan_gwlinux.a
BINS     := $(patsubst host_tools/c/%.c,$(BUILD)/bin/%,$(TOOL_SRC)) \
            $(patsubst tests/tools/%.c,$(BUILD)/bin/%,$(TTOOL_SRC)) \
            $(if $(GWD_MAIN),$(BUILD)/bin/dan-gatewayd)
UNITS    := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(UNIT_SRC))
ALL_LIBS  = $(if $(GWL_SRC),$(LIBGWL)) $(if $(GW_SRC),$(LIBGW)) $(if $(PORT_SRC),$(LIBPOSIX)) $(LIB)

.PHONY: demo objects all test unit unit-run pytest cross install clean deps-build deps-test deps-cross venv
.DELETE_ON_ERROR:

all: deps-build $(ALL_LIBS) $(BINS) venv

# ---- dependencies -------------------------------------------------------

DEBS_BUILD := gcc make pkg-config libgpiod-dev
DEBS_TEST  := libcmocka-dev python3-venv valgrind
DEBS_CROSS := gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi

# $(call ensure_debs,pkgs): install the Debian packages that are missing.
define ensure_debs
@missing=""; \
if command -v dpkg-query >/dev/null 2>&1; then \
  for p in $(1); do \
    dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'install ok installed' || missing="$$missing $$p"; \
  done; \
else \
  echo "note: not a Debian system; make sure these are installed:$(foreach p,$(1), $(p))"; \
fi; \
if [ -n "$$missing" ]; then \
  echo "installing Debian packages:$$missing"; \
  if [ "$$(id -u)" = 0 ]; then SUDO=""; \
  elif command -v sudo >/dev/null 2>&1; then SUDO="sudo"; \
  else echo "error: missing packages:$$missing; install them as root (apt-get install$$missing)" >&2; exit 1; fi; \
  export DEBIAN_FRONTEND=noninteractive; \
  { $$SUDO apt-get install -y --no-install-recommends $$missing || \
    { $$SUDO apt-get update && $$SUDO apt-get install -y --no-install-recommends $$missing; }; } \
  || { echo "error: could not install:$$missing (apt-get failed; install them by hand)" >&2; exit 1; }; \
fi
endef

deps-build:
	$(call ensure_debs,$(DEBS_BUILD))
deps-test: deps-build
	$(call ensure_debs,$(DEBS_TEST))
deps-cross:
	$(call ensure_debs,$(DEBS_CROSS))

# Python venv for the host tool and the end-to-end tests.
$(VENV)/.stamp: host_tools/requirements-test.txt $(wildcard host_tools/pyproject.toml)
	@$(PYTHON) -c 'import ensurepip' 2>/dev/null || $(MAKE) --no-print-directory deps-test
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r host_tools/requirements-test.txt
	@if [ -f host_tools/pyproject.toml ]; then \
	  $(VENV)/bin/pip install --quiet --disable-pip-version-check -e host_tools; fi
	@touch $@
venv: $(VENV)/.stamp

# ---- libraries and programs ----------------------------------------------

$(BUILD)/obj/src/%.o: src/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_ALL) -c $< -o $@
$(BUILD)/obj/src/port/%.o: src/port/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) $(GPIOD_CFLAGS) -c $< -o $@
$(BUILD)/obj/peripherals/can_gateway/%.o: peripherals/can_gateway/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_ALL) -Iperipherals/can_gateway -c $< -o $@
$(BUILD)/obj/peripherals/can_gateway/linux/%.o: peripherals/can_gateway/linux/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) $(GPIOD_CFLAGS) -Iperipherals/can_gateway -c $< -o $@
$(BUILD)/obj/host_tools/c/%.o: host_tools/c/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) -c $< -o $@
$(BUILD)/obj/tests/%.o: tests/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) -Iperipherals/can_gateway -Itests/unit -c $< -o $@

# Naming every object here keeps them from being treated as intermediate
# files (deleted after linking, and not rebuilt when a header changes).
objects: $(call obj,$(LIB_SRC) $(PORT_SRC) $(GW_SRC) $(GWD_MAIN) $(GWL_SRC) $(TOOL_SRC) $(TTOOL_SRC) $(UNIT_SRC) $(UNIT_HELP))

$(LIB): $(call obj,$(LIB_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^
$(LIBGWL): $(call obj,$(GWL_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^
$(LIBPOSIX): $(call obj,$(PORT_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^
$(LIBGW): $(call obj,$(GW_SRC))
	@mkdir -p $(@D)
	rm -f $@ && $(AR) rcs $@ $^


$(BUILD)/bin/%: $(BUILD)/obj/host_tools/c/%.o $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(GPIOD_LIBS) -lutil
$(BUILD)/bin/%: $(BUILD)/obj/tests/tools/%.o $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(GPIOD_LIBS) -lutil
$(BUILD)/bin/dan-gatewayd: $(call obj,$(GWD_MAIN)) $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(GPIOD_LIBS) -lutil -lm

-include $(shell find $(BUILD)/obj -name '*.d' 2>/dev/null)

# ---- tests ----------------------------------------------------------------

$(BUILD)/tests/test_%: $(BUILD)/obj/tests/unit/test_%.o $(call obj,$(UNIT_HELP)) $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ -lcmocka -lm

unit: deps-test all $(UNITS)

# Runs every unit test binary; fails if any fails.
unit-run: unit
	@fail=0; for t in $(UNITS); do \
	  echo "== $$t"; DAN_VECTORS=tests/vectors $$t || fail=1; \
	done; exit $$fail

pytest: all venv firmware
	CI=$${CI:-} $(VENV)/bin/python -m pytest -q tests/e2e

# The one-command demo: a DAN bus, the gateway and four DroneCAN ESCs on
# virtual wires, driven by danprobe.
demo: all venv
	$(VENV)/bin/python host_tools/demo.py

test: deps-test deps-firmware
	$(MAKE) --no-print-directory unit-run
	$(MAKE) --no-print-directory BUILD=build/asan SAN=1 unit-run
	$(MAKE) --no-print-directory pytest

# ---- firmware (Cortex-M4 under QEMU), size budget, portability -------------

include examples/fc_firmware/firmware.mk

# ---- benchmarks (make bench, make soak) and fuzzing (make fuzz) -------------

include tests/bench/bench.mk
include tests/fuzz/fuzz.mk

# ---- cross build ------------------------------------------------------------

CROSS_CC    := arm-none-eabi-gcc
CROSS_FLAGS := -mcpu=cortex-m4 -mthumb -Os -std=c99 -Wall -Wextra -Werror -Wconversion -Wshadow \
               -ffunction-sections -fdata-sections -Iinclude

cross: deps-cross
	@mkdir -p $(BUILD)/cross
	@for f in $(LIB_SRC); do \
	  $(CROSS_CC) $(CROSS_FLAGS) -c $$f -o $(BUILD)/cross/$$(basename $$f .c).o || exit 1; \
	done
	@arm-none-eabi-size -t $(BUILD)/cross/*.o

# ---- install ------------------------------------------------------------------

install: $(LIB)
	install -d $(DESTDIR)$(PREFIX)/include/dan $(DESTDIR)$(PREFIX)/lib/pkgconfig
	install -m 644 include/dan/*.h $(DESTDIR)$(PREFIX)/include/dan/
	install -m 644 $(LIB) $(DESTDIR)$(PREFIX)/lib/
	printf '%s\n' 'prefix=$(PREFIX)' 'includedir=$${prefix}/include' 'libdir=$${prefix}/lib' '' \
	  'Name: dan' 'Description: DAN v1 (Drone Area Network) protocol library' 'Version: $(VERSION)' \
	  'Cflags: -I$${includedir}' 'Libs: -L$${libdir} -ldan' > $(DESTDIR)$(PREFIX)/lib/pkgconfig/dan.pc

clean:
	rm -rf $(BUILD)

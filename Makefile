# DAN: libdan, the CAN-over-DAN gateway, tools and tests.
#
#   make            build libdan, the POSIX port, the peripheral types' libraries,
#                   the tools and the gateway daemon. Installs nothing: a missing
#                   package is named and the build stops.
#   make deps       install what building, testing and the demo need (Debian
#                   packages with apt-get, sudo when not root; .venv from PyPI)
#   make demo       deps, then the demo on a virtual bus
#   make test       deps, then C unit tests (plain and ASan+UBSan), the style
#                   check (C and Python) and the end-to-end tests
#   make style      the style check alone; make format rewrites the files
#   make cross      compile the portable sources for Cortex-M4, print sizes
#   make install    PREFIX=/usr/local DESTDIR= ; headers, libraries, .pc files

# No built-in implicit rules: with them, make tries to remake the included
# dependency files (*.d) through chains like `%: %.o`.
MAKEFLAGS += --no-builtin-rules
.SUFFIXES:

BUILD   ?= build
PREFIX  ?= /usr/local
DESTDIR ?=
CC      ?= cc
AR      ?= ar
PYTHON  ?= python3
VENV    := .venv
VERSION := 0.1.0

# The one set of warning flags, for every C file of the project.
WARN := -std=c99 -Wall -Wextra -Werror -Wconversion -Wshadow
OPT  ?= -O2 -g
SAN  ?=
ifeq ($(SAN),1)
OPT   := -O1 -g -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
LDSAN := -fsanitize=address,undefined
endif

# ---- what is built -----------------------------------------------------------

# libdan core: what every peripheral type uses.
CORE_SRC := $(wildcard src/*.c)
PORT_SRC := $(wildcard src/port/*.c)

# Peripheral types: one folder each under peripherals/, public headers in
# its include/ (dan/<type>/...). The CAN gateway type:
GW_DIR        := peripherals/can_gateway
GW_CLIENT_SRC := $(wildcard $(GW_DIR)/gw_msgs*.c $(GW_DIR)/gw_client*.c) $(GW_DIR)/f16.c $(GW_DIR)/gw_esc_map.c \
                 $(GW_DIR)/gw_file_name.c
GW_NODE_SRC   := $(wildcard $(GW_DIR)/gw_node*.c $(GW_DIR)/dsdl*.c) $(GW_DIR)/dronecan.c
GW_LINUX_SRC  := $(filter-out $(GW_DIR)/linux/dan-gatewayd.c,$(wildcard $(GW_DIR)/linux/*.c))
GWD_MAIN      := $(GW_DIR)/linux/dan-gatewayd.c

# The tools' shared helper (dan_tool.c) is a library, not a program.
TOOL_LIB_SRC := host_tools/c/dan_tool.c
TOOL_SRC  := $(filter-out $(TOOL_LIB_SRC),$(wildcard host_tools/c/*.c))
TTOOL_SRC := $(wildcard tests/tools/*.c)
UNIT_SRC  := $(wildcard tests/unit/test_*.c)
UNIT_HELP := $(filter-out $(UNIT_SRC),$(wildcard tests/unit/*.c))

# Everything an MCU build compiles: no POSIX, no allocation.
PORTABLE_SRC := $(CORE_SRC) $(GW_CLIENT_SRC) $(GW_NODE_SRC)

INCLUDES := -Iinclude $(patsubst %,-I%,$(wildcard peripherals/*/include))
CFLAGS_ALL   = $(WARN) $(OPT) $(INCLUDES) -MMD -MP $(EXTRA_CFLAGS)
# POSIX code (the port, tools, daemons, tests) may use POSIX and Linux.
CFLAGS_POSIX = $(CFLAGS_ALL) -D_GNU_SOURCE $(GPIOD_CFLAGS) -Ihost_tools/c

# libgpiod (v1 API) drives a direction pin. GPIOD=0 builds without it.
GPIOD ?= 1
ifeq ($(GPIOD),1)
GPIOD_CFLAGS := -DDAN_HAVE_GPIOD
GPIOD_LIBS   := -lgpiod
endif

obj = $(patsubst %.c,$(BUILD)/obj/%.o,$(1))

LIB        := $(BUILD)/libdan.a
LIBPOSIX   := $(BUILD)/libdan_posix.a
LIBGW      := $(BUILD)/libdan_can_gw.a
LIBGWNODE  := $(BUILD)/libdan_can_gw_node.a
LIBGWLINUX := $(BUILD)/libdan_can_gw_linux.a
LIBTOOL    := $(BUILD)/libdan_tool.a
ALL_LIBS   := $(LIBGWLINUX) $(LIBTOOL) $(LIBGWNODE) $(LIBGW) $(LIBPOSIX) $(LIB)
BINS       := $(patsubst host_tools/c/%.c,$(BUILD)/bin/%,$(TOOL_SRC)) \
              $(patsubst tests/tools/%.c,$(BUILD)/bin/%,$(TTOOL_SRC)) \
              $(BUILD)/bin/dan-gatewayd
UNITS      := $(patsubst tests/unit/%.c,$(BUILD)/tests/%,$(UNIT_SRC))

.PHONY: all demo objects test unit unit-run pytest style format cross install clean \
        deps deps-build deps-test check-deps venv
.DELETE_ON_ERROR:

all: check-deps $(ALL_LIBS) $(BINS)

# ---- dependencies --------------------------------------------------------------

DEBS_BUILD := gcc make pkg-config $(if $(filter 1,$(GPIOD)),libgpiod-dev)
DEBS_TEST  := libcmocka-dev python3-venv valgrind clang-format

# $(call missing_debs,pkgs): the shell word list of pkgs not installed.
missing_debs = $$(for p in $(1); do \
  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q 'install ok installed' || echo $$p; done)

# $(call ensure_debs,pkgs): install the Debian packages that are missing.
define ensure_debs
@if ! command -v dpkg-query >/dev/null 2>&1; then \
  echo "note: not a Debian system; make sure these are installed:$(foreach p,$(1), $(p))"; exit 0; fi; \
missing="$(call missing_debs,$(1))"; missing=$$(echo $$missing); \
if [ -n "$$missing" ]; then \
  echo "installing Debian packages: $$missing"; \
  if [ "$$(id -u)" = 0 ]; then SUDO=""; \
  elif command -v sudo >/dev/null 2>&1; then SUDO="sudo"; \
  else echo "error: missing packages: $$missing; install them as root (apt-get install $$missing)" >&2; exit 1; fi; \
  export DEBIAN_FRONTEND=noninteractive; \
  { $$SUDO apt-get install -y --no-install-recommends $$missing || \
    { $$SUDO apt-get update && $$SUDO apt-get install -y --no-install-recommends $$missing; }; } \
  || { echo "error: could not install: $$missing (apt-get failed; install them by hand)" >&2; exit 1; }; \
fi
endef

# Plain make only looks: it names what is missing and stops.
check-deps:
	@if command -v dpkg-query >/dev/null 2>&1; then \
	  missing="$(call missing_debs,$(DEBS_BUILD))"; missing=$$(echo $$missing); \
	  if [ -n "$$missing" ]; then \
	    echo "error: missing Debian packages: $$missing" >&2; \
	    echo "       run 'make deps' (installs them) or 'apt-get install $$missing'$(if $(filter 1,$(GPIOD)),; GPIOD=0 builds without libgpiod)" >&2; \
	    exit 1; fi; fi

deps-build:
	$(call ensure_debs,$(DEBS_BUILD))
deps-test: deps-build
	$(call ensure_debs,$(DEBS_TEST))
deps: deps-test deps-firmware venv

# Python venv for danprobe, the host tools and the end-to-end tests.
$(VENV)/.stamp: host_tools/requirements-test.txt host_tools/pyproject.toml
	@$(PYTHON) -c 'import ensurepip' 2>/dev/null || $(MAKE) --no-print-directory deps-test
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r host_tools/requirements-test.txt
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -e host_tools
	@touch $@
venv: $(VENV)/.stamp

# ---- libraries and programs ------------------------------------------------------

$(BUILD)/obj/src/port/%.o: src/port/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) -c $< -o $@
$(BUILD)/obj/$(GW_DIR)/linux/%.o: $(GW_DIR)/linux/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) -c $< -o $@
$(BUILD)/obj/host_tools/%.o: host_tools/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) -c $< -o $@
$(BUILD)/obj/tests/%.o: tests/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) -I$(GW_DIR)/linux -Itests/unit -c $< -o $@
# Portable sources (the core, the peripheral types): no POSIX.
$(BUILD)/obj/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_ALL) -c $< -o $@

# Naming every object here keeps them from being treated as intermediate
# files (deleted after linking, and not rebuilt when a header changes).
objects: $(call obj,$(CORE_SRC) $(PORT_SRC) $(GW_CLIENT_SRC) $(GW_NODE_SRC) $(GW_LINUX_SRC) \
                    $(GWD_MAIN) $(TOOL_SRC) $(TOOL_LIB_SRC) $(TTOOL_SRC) $(UNIT_SRC) $(UNIT_HELP))

# Each library with the variable naming its sources, one rule for all.
LIB_SOURCES := $(LIB)=CORE_SRC $(LIBPOSIX)=PORT_SRC $(LIBGW)=GW_CLIENT_SRC \
               $(LIBGWNODE)=GW_NODE_SRC $(LIBGWLINUX)=GW_LINUX_SRC $(LIBTOOL)=TOOL_LIB_SRC
# $(call archive_rule,library,sources variable)
define archive_rule
$(1): $$(call obj,$$($(2)))
	@mkdir -p $$(@D)
	rm -f $$@ && $$(AR) rcs $$@ $$^
endef
$(foreach l,$(LIB_SOURCES),$(eval $(call archive_rule,$(word 1,$(subst =, ,$(l))),$(word 2,$(subst =, ,$(l))))))

LDLIBS := $(GPIOD_LIBS) -lutil -lm
$(BUILD)/bin/%: $(BUILD)/obj/host_tools/c/%.o $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(LDLIBS)
$(BUILD)/bin/%: $(BUILD)/obj/tests/tools/%.o $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(LDLIBS)
# The test-a type's handlers, shared with the unit tests.
$(BUILD)/bin/dan-testperiph: $(BUILD)/obj/tests/tools/dan-testperiph.o \
                             $(BUILD)/obj/tests/unit/handlers_test_a.o $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(LDLIBS)
# dan-fcsim keeps the telemetry of 20 ESCs (all one ESC_CMD drives): it is
# built with DAN_GW_MAX_ESC=20 together with its own copy of the client,
# since dan_gw_t's layout depends on it (the library's default is 4).
FCSIM_DEFS   := -DDAN_GW_MAX_ESC=20u
FCSIM_GW_OBJ := $(patsubst %.c,$(BUILD)/obj/fcsim/%.o,$(GW_CLIENT_SRC))
$(BUILD)/obj/fcsim/%.o: %.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_ALL) $(FCSIM_DEFS) -c $< -o $@
$(BUILD)/obj/tests/tools/dan-fcsim.o: tests/tools/dan-fcsim.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) $(FCSIM_DEFS) -c $< -o $@
# its step files (tests/tools/fcsim/), with the same dan_gw_t layout
FCSIM_OBJ := $(patsubst %.c,$(BUILD)/obj/%.o,$(wildcard tests/tools/fcsim/*.c))
$(BUILD)/obj/tests/tools/fcsim/%.o: tests/tools/fcsim/%.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS_POSIX) $(FCSIM_DEFS) -Itests/tools -c $< -o $@
$(BUILD)/bin/dan-fcsim: $(BUILD)/obj/tests/tools/dan-fcsim.o $(FCSIM_OBJ) $(FCSIM_GW_OBJ) \
                        $(filter-out $(LIBGW),$(ALL_LIBS))
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(LDLIBS)
$(BUILD)/bin/dan-gatewayd: $(call obj,$(GWD_MAIN)) $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ $(LDLIBS)

-include $(shell find $(BUILD)/obj -name '*.d' 2>/dev/null)

# ---- tests ----------------------------------------------------------------------

$(BUILD)/tests/test_%: $(BUILD)/obj/tests/unit/test_%.o $(call obj,$(UNIT_HELP)) $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(LDSAN) -o $@ $^ -lcmocka $(LDLIBS)

unit: all $(UNITS)

# Runs every unit test binary; fails if any fails.
unit-run: unit
	@fail=0; for t in $(UNITS); do \
	  echo "== $$t"; DAN_VECTORS=tests/vectors $$t || fail=1; \
	done; exit $$fail

# The e2e tests mostly wait on virtual wires and timers (about 1.4 of the 2
# cores busy with three workers): four workers, each test given to the next
# free one (no test shares a rig with another), keep `make test` well under
# its 10-minute budget on 2 cores. PYTEST_JOBS=0 runs them in one process.
PYTEST_JOBS ?= 4
pytest: all venv firmware
	CI=$${CI:-} $(VENV)/bin/python -m pytest -q -n $(PYTEST_JOBS) --dist load tests/e2e

# One formatter for C (clang-format, .clang-format) and one for Python
# (ruff, pyproject.toml at the top): `make style` fails on any difference.
STYLE_C  = $(shell git ls-files '*.c' '*.h' 2>/dev/null)
STYLE_PY = $(shell git ls-files '*.py' 2>/dev/null)
style: venv
	@clang-format --dry-run --Werror $(STYLE_C) && echo "style: C ok ($(words $(STYLE_C)) files)"
	@$(VENV)/bin/ruff format --check --quiet $(STYLE_PY) && $(VENV)/bin/ruff check --quiet $(STYLE_PY) \
	  && echo "style: Python ok ($(words $(STYLE_PY)) files)"
	@$(VENV)/bin/python tests/style/check_functions.py
	@$(VENV)/bin/python tests/style/check_braces.py
format: venv
	clang-format -i $(STYLE_C)
	$(VENV)/bin/ruff format --quiet $(STYLE_PY)

# The one-command demo: a DAN bus, the gateway and four DroneCAN ESCs on
# virtual wires, driven by danprobe.
demo: deps all
	$(VENV)/bin/python host_tools/demo.py

# The builds use every core (the sequence of steps stays in this order).
NPROC := $(shell nproc 2>/dev/null || echo 2)
test: deps
	$(MAKE) --no-print-directory -j$(NPROC) unit-run
	$(MAKE) --no-print-directory -j$(NPROC) BUILD=build/asan SAN=1 unit-run
	$(MAKE) --no-print-directory style
	$(MAKE) --no-print-directory -j$(NPROC) all firmware
	$(MAKE) --no-print-directory pytest

# ---- firmware (Cortex-M4 under QEMU), size budget, portability -------------------

include examples/fc_firmware/firmware.mk

# ---- benchmarks (make bench, make soak) and fuzzing (make fuzz) --------------------

include tests/bench/bench.mk
include tests/fuzz/fuzz.mk

# ---- cross build ----------------------------------------------------------------

CROSS_CC    := arm-none-eabi-gcc
CROSS_FLAGS := -mcpu=cortex-m4 -mthumb -Os $(WARN) -ffunction-sections -fdata-sections $(INCLUDES)

cross: deps-firmware
	@mkdir -p $(BUILD)/cross
	@for f in $(PORTABLE_SRC); do \
	  $(CROSS_CC) $(CROSS_FLAGS) -c $$f -o $(BUILD)/cross/$$(basename $$f .c).o || exit 1; \
	done
	@arm-none-eabi-size -t $(BUILD)/cross/*.o

# ---- install ---------------------------------------------------------------------

# $(call pc_file,name,description,libs,requires)
define pc_file
printf '%s\n' 'prefix=$(PREFIX)' 'includedir=$${prefix}/include' 'libdir=$${prefix}/lib' '' \
  'Name: $(1)' 'Description: $(2)' 'Version: $(VERSION)' $(if $(4),'Requires: $(4)') \
  'Cflags: -I$${includedir}' 'Libs: -L$${libdir} $(3)' > $(DESTDIR)$(PREFIX)/lib/pkgconfig/$(1).pc
endef

install: $(LIB) $(LIBPOSIX) $(LIBGW) $(LIBGWNODE)
	install -d $(DESTDIR)$(PREFIX)/include/dan/can_gw $(DESTDIR)$(PREFIX)/lib/pkgconfig
	install -m 644 include/dan/*.h $(DESTDIR)$(PREFIX)/include/dan/
	install -m 644 $(GW_DIR)/include/dan/can_gw/*.h $(DESTDIR)$(PREFIX)/include/dan/can_gw/
	install -m 644 $(LIB) $(LIBPOSIX) $(LIBGW) $(LIBGWNODE) $(DESTDIR)$(PREFIX)/lib/
	$(call pc_file,dan,DAN v1 (Drone Area Network) protocol library,-ldan)
	$(call pc_file,dan-posix,DAN POSIX port (raw tty at any baud; libgpiod direction pin),-ldan_posix $(GPIOD_LIBS),dan)
	$(call pc_file,dan-can-gw,DAN CAN-over-DAN gateway client (FC side),-ldan_can_gw,dan)
	$(call pc_file,dan-can-gw-node,DAN CAN-over-DAN gateway node (DroneCAN side),-ldan_can_gw_node -ldan_can_gw,dan)

clean:
	rm -rf $(BUILD)

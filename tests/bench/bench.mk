# Benchmarks (not part of `make test`). Included by the Makefile; uses its
# BUILD, CC, WARN, INCLUDES, LDLIBS, VENV, ALL_LIBS, deps and all.
#
#   make bench                 one table of ratios; build/bench/results.json
#                              (+ a timestamped copy), delta vs the previous run
#   make bench BENCH_ARGS='--only esc,parser --seconds 10'
#   make bench SOAK=600        the full ESC loop for 600 s: RSS and counters
#   make soak [SOAK=300]       the same (default 300 s)
#   make soak CHAOS=1 SOAK=600 the chaos soak (tests/bench/chaos.py): faults on a
#                              seeded schedule, invariants checked; chaos.json
#   make restarts [RESTARTS=100] [RESTART_BAUDS=115200,1000000,2000000]
#                              the FC and the gateway each killed RESTARTS times
#                              at random moments (tests/bench/restarts.py);
#                              build/bench/restarts.json

BENCH_DIR   := $(BUILD)/bench
BENCH_CFLAGS = $(WARN) -O2 -g $(INCLUDES) -D_GNU_SOURCE
BENCH_BINS   = $(BENCH_DIR)/bench_parser $(BENCH_DIR)/bench_gateway $(BENCH_DIR)/bench_esc_sim \
               $(BENCH_DIR)/bench_pty_rtt
SOAK        ?=
BENCH_ARGS  ?=

.PHONY: bench soak restarts bench-build
RESTARTS      ?= 100
RESTART_BAUDS ?= 115200,1000000,2000000

$(BENCH_DIR)/bench_%: tests/bench/bench_%.c $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(BENCH_CFLAGS) -o $@ $^ $(LDLIBS)

# The gateway benchmarks share bench_escs.c; the ESC loops in simulated
# time run on the unit tests' simulated wire.
$(BENCH_DIR)/bench_gateway: tests/bench/bench_gateway.c tests/bench/bench_escs.c $(ALL_LIBS)
	@mkdir -p $(@D)
	$(CC) $(BENCH_CFLAGS) -o $@ $^ $(LDLIBS)

# It drives up to 8 ESCs: built with DAN_GW_MAX_ESC=8 (the library's
# default is 4) together with its own copy of the client, since dan_gw_t's
# layout depends on it.
$(BENCH_DIR)/bench_esc_sim: tests/bench/bench_esc_sim.c tests/bench/bench_escs.c tests/unit/simbus.c \
                            $(GW_CLIENT_SRC) $(filter-out $(LIBGW),$(ALL_LIBS))
	@mkdir -p $(@D)
	$(CC) $(BENCH_CFLAGS) -DDAN_GW_MAX_ESC=8u -Itests/unit -o $@ $^ $(LDLIBS)

bench-build: deps all $(BENCH_BINS)

bench: bench-build
	$(VENV)/bin/python tests/bench/run_bench.py --build $(BUILD) --out $(BENCH_DIR) \
	  $(if $(SOAK),--soak $(SOAK)) $(BENCH_ARGS)

soak: bench-build
ifeq ($(CHAOS),1)
	@mkdir -p $(BENCH_DIR)
	$(VENV)/bin/python tests/bench/chaos.py --build $(BUILD) --seconds $(or $(SOAK),300) \
	  --out $(BENCH_DIR)/chaos.json
else
	$(VENV)/bin/python tests/bench/run_bench.py --build $(BUILD) --out $(BENCH_DIR) --soak $(or $(SOAK),300)
endif

restarts: bench-build
	@mkdir -p $(BENCH_DIR)
	$(VENV)/bin/python tests/bench/restarts.py --build $(BUILD) --count $(RESTARTS) \
	  --bauds $(RESTART_BAUDS) --out $(BENCH_DIR)/restarts.json

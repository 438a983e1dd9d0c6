# Fuzzing with libFuzzer + ASan + UBSan (Debian clang 14). Included by the
# Makefile; uses its BUILD, WARN, INCLUDES, the source lists and ensure_debs.
# What each target covers and checks: docs/FUZZING.md.
#
#   make fuzz                    every target for FUZZ_SECONDS (default 30) each
#   make fuzz FUZZ_TARGETS=frame FUZZ_SECONDS=300
#   make fuzz-long               every target to FUZZ_RUNS (10^7) executions
#   make fuzz-cov                line coverage of the corpus over the decoders
#                                and handlers (llvm-cov; FUZZ_COV_FAIL=90 fails
#                                below 90 %)
#   make fuzz-build              just the binaries (build/fuzz/bin/fuzz_<target>)
#   make fuzz-corpus             regenerate tests/fuzz/corpus from tests/vectors
#
# Seeds come from tests/fuzz/corpus/<target>/ (in the repository, read only);
# what a run learns goes to build/fuzz/work/<target>/. A crash (or leak, or
# timeout) is copied to tests/fuzz/regressions/<target>/, which `make test`
# replays through tests/unit/test_fuzz_regressions.c, and the run fails.
# tests/fuzz/run.sh runs the targets and prints the summary.

FUZZ_SECONDS ?= 30
FUZZ_RUNS    ?= 10000000
FUZZ_TARGETS ?= frame payloads gw_handlers dronecan_rx dsdl slcan gw_client dna file_names \
                file_dir gw_msgs
FUZZ_CC      ?= clang-14
FUZZ_DIR     := $(BUILD)/fuzz
FUZZ_SAN     := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
FUZZ_CFLAGS  := $(WARN) -g -O1 -D_GNU_SOURCE $(INCLUDES) -I$(GW_DIR)/linux -Ihost_tools/c -Itests/fuzz -Itests/unit \
                $(FUZZ_SAN) -fsanitize=fuzzer-no-link
# (the SLCAN backend waits with the tools' helper, and src/port for its clock)
FUZZ_LIBSRC   = $(CORE_SRC) $(GW_CLIENT_SRC) $(GW_NODE_SRC) $(GW_LINUX_SRC) $(TOOL_LIB_SRC) \
                $(PORT_SRC) tests/unit/file_store_ram.c tests/fuzz/targets.c \
                tests/fuzz/targets_files.c tests/fuzz/targets_msgs.c
FUZZ_OBJS     = $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(FUZZ_LIBSRC))
FUZZ_BINS     = $(patsubst %,$(FUZZ_DIR)/bin/fuzz_%,$(FUZZ_TARGETS))

.PHONY: fuzz fuzz-long fuzz-cov fuzz-build fuzz-corpus deps-fuzz deps-fuzz-cov

deps-fuzz:
	$(call ensure_debs,clang-14 libclang-rt-14-dev)

$(FUZZ_DIR)/obj/%.o: %.c | deps-fuzz
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/bin/fuzz_%: tests/fuzz/fuzz_main.c $(FUZZ_OBJS)
	@mkdir -p $(@D)
	@echo "link $@"
	@$(FUZZ_CC) $(FUZZ_CFLAGS) -DDAN_FUZZ_FN=dan_fuzz_$* -fsanitize=fuzzer -o $@ $^ -lm

.SECONDARY: $(FUZZ_OBJS)

-include $(shell find $(FUZZ_DIR)/obj -name '*.d' 2>/dev/null)

fuzz-build: $(FUZZ_BINS)

fuzz-corpus:
	python3 tests/fuzz/gen_corpus.py

# Each target in turn, nice'd (the machine stays usable); the summary has
# executions, seconds, cov/ft and crashes per target; fails on a finding.
fuzz: fuzz-build
	@FUZZ_DIR=$(FUZZ_DIR) nice -n 10 sh tests/fuzz/run.sh seconds $(FUZZ_SECONDS) $(FUZZ_TARGETS)

# The long run: FUZZ_RUNS executions of every target (10^7 by default).
fuzz-long: fuzz-build
	@FUZZ_DIR=$(FUZZ_DIR) nice -n 10 sh tests/fuzz/run.sh runs $(FUZZ_RUNS) $(FUZZ_TARGETS)

# ---- coverage of the corpus (make fuzz-cov) ------------------------------------
# The same sources built with clang's source-based coverage (no sanitizer, no
# libFuzzer), tests/fuzz/replay_main.c replaying tests/fuzz/corpus/<target>,
# build/fuzz/work/<target> (what fuzz runs learned) and the regressions; the
# report covers the decoders and handlers (FUZZ_COV_SRC).
FUZZ_COV_DIR    := $(FUZZ_DIR)/cov
FUZZ_COV_CFLAGS := $(WARN) -g -O0 -D_GNU_SOURCE $(INCLUDES) -I$(GW_DIR)/linux -Ihost_tools/c \
                   -Itests/fuzz -Itests/unit -fprofile-instr-generate -fcoverage-mapping
FUZZ_COV_OBJS    = $(patsubst %.c,$(FUZZ_COV_DIR)/obj/%.o,$(FUZZ_LIBSRC))
FUZZ_COV_BINS    = $(patsubst %,$(FUZZ_COV_DIR)/bin/cov_%,$(FUZZ_TARGETS))
FUZZ_COV_SRC     = src/frame.c src/payloads.c src/common.c $(wildcard $(GW_DIR)/gw_msgs*.c) \
                   $(wildcard $(GW_DIR)/gw_node*.c) $(GW_DIR)/dronecan.c $(wildcard $(GW_DIR)/dsdl*.c) \
                   $(GW_DIR)/gw_file_name.c \
                   $(GW_DIR)/linux/can_slcan.c $(GW_DIR)/linux/file_dir.c
FUZZ_COV_FAIL   ?= 0

deps-fuzz-cov:
	$(call ensure_debs,clang-14 llvm-14)

$(FUZZ_COV_DIR)/obj/%.o: %.c | deps-fuzz-cov
	@mkdir -p $(@D)
	@$(FUZZ_CC) $(FUZZ_COV_CFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_COV_DIR)/bin/cov_%: tests/fuzz/replay_main.c $(FUZZ_COV_OBJS)
	@mkdir -p $(@D)
	@$(FUZZ_CC) $(FUZZ_COV_CFLAGS) -DDAN_FUZZ_FN=dan_fuzz_$* -o $@ $^ -lm

.SECONDARY: $(FUZZ_COV_OBJS)

-include $(shell find $(FUZZ_COV_DIR)/obj -name '*.d' 2>/dev/null)

fuzz-cov: $(FUZZ_COV_BINS)
	@rm -rf $(FUZZ_COV_DIR)/prof && mkdir -p $(FUZZ_COV_DIR)/prof
	@for t in $(FUZZ_TARGETS); do \
	  printf '%-12s ' $$t; \
	  LLVM_PROFILE_FILE=$(FUZZ_COV_DIR)/prof/$$t.profraw $(FUZZ_COV_DIR)/bin/cov_$$t \
	    tests/fuzz/corpus/$$t $(FUZZ_DIR)/work/$$t tests/fuzz/regressions/$$t || exit 1; \
	done
	@llvm-profdata-14 merge -sparse $(FUZZ_COV_DIR)/prof/*.profraw -o $(FUZZ_COV_DIR)/fuzz.profdata
	@python3 tests/fuzz/cov_report.py --llvm-cov llvm-cov-14 --profdata $(FUZZ_COV_DIR)/fuzz.profdata \
	  --out $(FUZZ_COV_DIR) --fail-under $(FUZZ_COV_FAIL) $(addprefix --object ,$(FUZZ_COV_BINS)) \
	  $(FUZZ_COV_SRC)

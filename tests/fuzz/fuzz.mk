# Fuzzing with libFuzzer + ASan + UBSan (Debian clang 14). Included by the
# Makefile; uses its BUILD, WARN, INCLUDES, the source lists and ensure_debs.
#
#   make fuzz                    every target for FUZZ_SECONDS (default 30) each
#   make fuzz FUZZ_TARGETS=frame FUZZ_SECONDS=300
#   make fuzz-build              just the binaries (build/fuzz/bin/fuzz_<target>)
#   make fuzz-corpus             regenerate tests/fuzz/corpus from tests/vectors
#
# Seeds come from tests/fuzz/corpus/<target>/ (in the repository, read only);
# what a run learns goes to build/fuzz/work/<target>/. A crash (or leak, or
# timeout) is copied to tests/fuzz/regressions/<target>/, which `make test`
# replays through tests/unit/test_fuzz_regressions.c, and the run fails.

FUZZ_SECONDS ?= 30
FUZZ_TARGETS ?= frame payloads gw_handlers dronecan_rx dsdl slcan gw_client dna
FUZZ_CC      ?= clang-14
FUZZ_DIR     := $(BUILD)/fuzz
FUZZ_SAN     := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
FUZZ_CFLAGS  := $(WARN) -g -O1 -D_GNU_SOURCE $(INCLUDES) -I$(GW_DIR)/linux -Ihost_tools/c -Itests/fuzz -Itests/unit \
                $(FUZZ_SAN) -fsanitize=fuzzer-no-link
# (the SLCAN backend waits with the tools' helper, and src/port for its clock)
FUZZ_LIBSRC   = $(CORE_SRC) $(GW_CLIENT_SRC) $(GW_NODE_SRC) $(GW_LINUX_SRC) $(TOOL_LIB_SRC) \
                $(PORT_SRC) tests/unit/file_store_ram.c tests/fuzz/targets.c
FUZZ_OBJS     = $(patsubst %.c,$(FUZZ_DIR)/obj/%.o,$(FUZZ_LIBSRC))
FUZZ_BINS     = $(patsubst %,$(FUZZ_DIR)/bin/fuzz_%,$(FUZZ_TARGETS))

.PHONY: fuzz fuzz-build fuzz-corpus deps-fuzz

deps-fuzz:
	$(call ensure_debs,clang-14 libclang-rt-14-dev)

$(FUZZ_DIR)/obj/%.o: %.c | deps-fuzz
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -MMD -MP -c $< -o $@

$(FUZZ_DIR)/bin/fuzz_%: tests/fuzz/fuzz_main.c $(FUZZ_OBJS)
	@mkdir -p $(@D)
	$(FUZZ_CC) $(FUZZ_CFLAGS) -DDAN_FUZZ_FN=dan_fuzz_$* -fsanitize=fuzzer -o $@ $^ -lm

.SECONDARY: $(FUZZ_OBJS)

-include $(shell find $(FUZZ_DIR)/obj -name '*.d' 2>/dev/null)

fuzz-build: $(FUZZ_BINS)

fuzz-corpus:
	python3 tests/fuzz/gen_corpus.py

# Runs each target in turn; prints one summary line per target (executions,
# coverage, crashes) and fails if any target crashed.
fuzz: fuzz-build
	@fail=0; summary=""; \
	for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_DIR)/work/$$t $(FUZZ_DIR)/artifacts/$$t; \
	  echo "== fuzz_$$t for $(FUZZ_SECONDS) s"; \
	  $(FUZZ_DIR)/bin/fuzz_$$t -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 \
	    -max_len=4096 -rss_limit_mb=2048 -timeout=10 \
	    -artifact_prefix=$(FUZZ_DIR)/artifacts/$$t/ \
	    $(FUZZ_DIR)/work/$$t tests/fuzz/corpus/$$t > $(FUZZ_DIR)/$$t.log 2>&1; rc=$$?; \
	  execs=$$(sed -n 's/^stat::number_of_executed_units: *//p' $(FUZZ_DIR)/$$t.log | tail -1); \
	  cov=$$(grep -o 'cov: [0-9]*' $(FUZZ_DIR)/$$t.log | tail -1 | cut -d' ' -f2); \
	  crashes=0; \
	  for a in $(FUZZ_DIR)/artifacts/$$t/*; do \
	    [ -f "$$a" ] || continue; crashes=$$((crashes+1)); \
	    mkdir -p tests/fuzz/regressions/$$t; \
	    cp "$$a" tests/fuzz/regressions/$$t/$$(basename "$$a"); \
	    echo "   crash input saved as tests/fuzz/regressions/$$t/$$(basename "$$a")"; \
	  done; \
	  if [ $$rc -ne 0 ] || [ $$crashes -ne 0 ]; then fail=1; tail -40 $(FUZZ_DIR)/$$t.log; fi; \
	  line=$$(printf '%-12s %10s execs  cov %5s  crashes %s  (exit %s)' $$t "$${execs:-?}" "$${cov:-?}" $$crashes $$rc); \
	  echo "   $$line"; summary="$$summary$$line\n"; \
	done; \
	printf "\nfuzz summary (%s s each; logs in $(FUZZ_DIR)/<target>.log):\n$$summary" $(FUZZ_SECONDS); \
	exit $$fail

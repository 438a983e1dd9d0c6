#!/bin/sh
# Runs libFuzzer targets one after the other (tests/fuzz/fuzz.mk: make fuzz,
# make fuzz-long) and prints one line per target: executions, time taken,
# coverage (cov: edges, ft: features), crashes. Exits 1 if any target
# crashed (or leaked, timed out, ran out of memory); the input that did it
# is copied to tests/fuzz/regressions/<target>/ for `make test` to replay.
#
#   tests/fuzz/run.sh seconds 30 frame dna     each target for 30 s
#   tests/fuzz/run.sh runs 10000000 frame      each target to 10^7 executions
#
# FUZZ_DIR (build/fuzz) holds bin/, the learned corpus work/<target>/ and the
# logs; seeds come from tests/fuzz/corpus/<target>/ (read only).
set -u
mode=$1
amount=$2
shift 2
dir=${FUZZ_DIR:-build/fuzz}

# Longest input per target: enough for every state the input can reach
# (several frames, a script of requests, a multi-frame transfer), short
# enough that an execution stays cheap (docs/FUZZING.md).
max_len() {
    case $1 in
    payloads | gw_client | gw_msgs) echo 256 ;;
    slcan | file_names) echo 256 ;;
    dsdl) echo 512 ;;
    file_dir) echo 256 ;;
    frame | dna) echo 1024 ;;
    *) echo 2048 ;; # gw_handlers, dronecan_rx
    esac
}

case $mode in
seconds) limit="-max_total_time=$amount" ;;
runs) limit="-runs=$amount" ;;
*)
    echo "usage: $0 seconds|runs N target..." >&2
    exit 2
    ;;
esac

fail=0
summary=""
for t in "$@"; do
    work=$dir/work/$t
    art=$dir/artifacts/$t
    log=$dir/$t.log
    mkdir -p "$work" "$art"
    rm -f "$art"/* # earlier findings are in tests/fuzz/regressions already
    echo "== fuzz_$t ($mode $amount, max_len $(max_len "$t"))"
    start=$(date +%s)
    "$dir/bin/fuzz_$t" "$limit" -print_final_stats=1 -max_len="$(max_len "$t")" \
        -rss_limit_mb=2048 -timeout=10 -artifact_prefix="$art/" \
        "$work" "tests/fuzz/corpus/$t" >"$log" 2>&1
    rc=$?
    secs=$(($(date +%s) - start))
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
    last=$(grep -E '^#[0-9]+' "$log" | tail -1)
    cov=$(echo "$last" | sed -n 's/.* cov: \([0-9]*\).*/\1/p')
    ft=$(echo "$last" | sed -n 's/.* ft: \([0-9]*\).*/\1/p')
    crashes=0
    for a in "$art"/*; do
        [ -f "$a" ] || continue
        crashes=$((crashes + 1))
        mkdir -p "tests/fuzz/regressions/$t"
        cp "$a" "tests/fuzz/regressions/$t/$(basename "$a")"
        echo "   finding saved as tests/fuzz/regressions/$t/$(basename "$a")"
    done
    if [ "$rc" -ne 0 ] || [ "$crashes" -ne 0 ]; then
        fail=1
        tail -40 "$log"
    fi
    rate=$((${execs:-0} / (secs > 0 ? secs : 1)))
    line=$(printf '%-12s %11s execs %7s s %8s/s  cov %5s  ft %6s  crashes %s%s' "$t" \
        "${execs:-?}" "$secs" "$rate" "${cov:-?}" "${ft:-?}" "$crashes" \
        "$([ "$rc" -ne 0 ] && echo "  (exit $rc)")")
    echo "   $line"
    summary="$summary$line
"
done
printf '\nfuzz summary (%s %s each; logs in %s/<target>.log):\n%s' "$mode" "$amount" "$dir" "$summary"
[ "$fail" -eq 0 ] && echo "no findings" || echo "FINDINGS: see above"
exit $fail

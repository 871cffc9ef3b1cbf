# tests/lib.sh: what every shell test shares: the pass, fail and skip counters, the
# helpers that count a check, and the summary line tests/run.sh reads. Sourced (not run)
# by each tests/*.sh once it has changed to the repository root:
#     . tests/lib.sh NAME         (NAME starts the summary line: "NAME: N passed, N failed")
# A test sets `tmp` (its scratch folder) before it uses the helpers that run a command:
# they keep the command's output in $tmp/out and $tmp/err and show the first lines of
# $tmp/err under a failure (ko does too once the test sets lib_ko_shows_err=1). A
# test's last line is `summary`, whose status is the script's.
#
#   ok [NAME]                    a check passed ("ok NAME" when named)
#   ko NAME                      a check failed ("FAIL NAME")
#   skipped NAME                 a check that cannot run here ("skipped NAME"); the
#                                summary adds ", N skipped"
#   check NAME CMD...            CMD exits 0
#   check_status NAME STATUS     STATUS (a command's $?) is 0
#   expect_exit NAME CODE RE CMD...
#                                CMD exits CODE and its stderr matches the extended
#                                regular expression RE (case-insensitive)
#   summary                      prints the line; returns non-zero after a failure

lib_name=${1:-$(basename "$0" .sh)}
lib_ko_shows_err=0
pass=0; fail=0; skip=0

ok() { pass=$((pass + 1)); if [ $# -gt 0 ]; then echo "ok $1"; fi; return 0; }

ko() {
    fail=$((fail + 1))
    echo "FAIL $1"
    if [ "$lib_ko_shows_err" = 1 ]; then show_err; fi
    return 0
}

# The first lines of the last command's stderr, indented.
show_err() { if [ -n "${tmp:-}" ] && [ -s "$tmp/err" ]; then sed 's/^/    /' "$tmp/err" | head -n 5; fi; return 0; }

skipped() { skip=$((skip + 1)); echo "skipped $1"; }

check() {
    local name=$1; shift
    if "$@" >"$tmp/out" 2>"$tmp/err"; then ok "$name"; else ko "$name"; [ "$lib_ko_shows_err" = 1 ] || show_err; fi
}

check_status() {
    if [ "$2" -eq 0 ]; then ok; else ko "$1"; fi
}

expect_exit() {
    local name=$1 code=$2 re=$3; shift 3
    "$@" >"$tmp/out" 2>"$tmp/err"; local rc=$?
    if [ $rc -eq "$code" ] && grep -Eqi -- "$re" "$tmp/err"; then ok "$name"; else echo "    exit $rc"; ko "$name"; [ "$lib_ko_shows_err" = 1 ] || show_err; fi
}

summary() {
    if [ "$skip" -gt 0 ]; then echo "$lib_name: $pass passed, $fail failed, $skip skipped"
    else echo "$lib_name: $pass passed, $fail failed"; fi
    [ "$fail" -eq 0 ]
}

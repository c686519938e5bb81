#!/usr/bin/env bash
# Runs each test binary, shows its output, and closes with one line "tests: N passed, N failed".
# cmocka binaries report "[  PASSED  ] N test(s)." / "[  FAILED  ] N test(s)"; a binary that
# prints neither counts as one test, passed when it exits 0. Binaries named in $VALGRIND run
# under valgrind, whose errors fail them.
set -u
pass=0; fail=0; skip=0
for t in "$@"; do
  echo "== $t"
  case " ${VALGRIND:-} " in
    *" $t "*) out=$(valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite,indirect "$t" 2>&1); rc=$? ;;
    *) out=$("$t" 2>&1); rc=$? ;;
  esac
  echo "$out"
  p=$(echo "$out" | sed -n 's/.*\[  PASSED  \] \([0-9]*\) test.*/\1/p' | tail -1)
  f=$(echo "$out" | sed -n 's/.*\[  FAILED  \] \([0-9]*\) test.*/\1/p' | tail -1)
  s=$(echo "$out" | sed -n 's/.*\[  SKIPPED \] \([0-9]*\) test.*/\1/p' | tail -1)
  if [ -z "$p$f" ]; then
    if [ $rc -eq 0 ]; then pass=$((pass + 1)); else fail=$((fail + 1)); fi
  else
    pass=$((pass + ${p:-0})); fail=$((fail + ${f:-0})); skip=$((skip + ${s:-0}))
    [ $rc -ne 0 ] && [ -z "$f" ] && fail=$((fail + 1))
  fi
done
echo "tests: $pass passed, $fail failed, $skip skipped"
[ $fail -eq 0 ]

#!/usr/bin/env bash
# Commands stopped by a signal, and what `ps` finds of them 5 s later (nothing should be left): a run (12
# single-object trials, 2 workers) stopped by SIGTERM and by SIGKILL, a benchmark stopped by SIGTERM, and an
# import stopped by SIGTERM and by SIGKILL during CoACD. Run from the repository root with the venv:
#   bash results/integrity/signals.sh > results/integrity/signals.md
set -u
KB=${KB:-.venv/bin/kgn-bench}
W=$(mktemp -d /tmp/kgn-signals.XXXX)
count() { cat "$@" 2>/dev/null | grep -c .; }

# stop TITLE SIG READY -- COMMAND...: start COMMAND, wait until the shell test READY holds, send SIG, then list
# what is left of the command and its children 5 s later.
stop() {
  local title=$1 sig=$2 ready=$3; shift 4
  "$@" > /dev/null 2>&1 &
  local main=$!
  until eval "$ready"; do sleep 0.1; done
  local kids; kids=$(pgrep -d, -P $main)  # workers, multiprocessing's resource tracker, CoACD's child
  kill -$sig $main; wait $main; local rc=$?
  sleep 5
  echo "## $title, SIG$sig: exit $rc; children were $kids"
  echo '```'
  ps -o pid,ppid,stat,etime,rss,cmd -p "$kids,$main" | sed "s#$W#W#g"
  echo '```'
}

for sig in TERM KILL; do
  run=(run single_object --detector kgnv2 --trials 2 --workers 2 --quiet --out $W/run_$sig)
  stop "run" $sig "[ \$(count $W/run_$sig/trials.jsonl) -ge 4 ]" -- $KB "${run[@]}"
  $KB "${run[@]}" > /dev/null 2>&1
  echo "rerun: exit $?, $(count $W/run_$sig/trials.jsonl) trials"
  echo
done
stop "benchmark" TERM "[ \$(count $W/bm/*/oracle/trials.jsonl) -ge 4 ]" -- \
  $KB benchmark --tasks single_object multi_object --detectors oracle --workers 2 --no-viewpoints --runs $W/bm --out $W/bm
.venv/bin/python -c "import trimesh; trimesh.creation.torus(0.05, 0.015, major_sections=300, minor_sections=60).export('$W/torus.ply')"
for sig in TERM KILL; do
  stop "objects add (during CoACD)" $sig "pgrep -P \$! > /dev/null && sleep 1" -- \
    $KB objects add $W/torus.ply --name torus_x --root $W/lib_$sig
  echo "library folder after: $(ls -A $W/lib_$sig 2>/dev/null | grep -v '^\.cache$' | tr '\n' ' ')"
done
rm -rf "$W"

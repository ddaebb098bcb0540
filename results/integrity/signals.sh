#!/usr/bin/env bash
# A run (12 single-object trials) with 2 workers stopped by SIGTERM, then by SIGKILL, and an import stopped by SIGTERM; 5 s later, `ps`
# lists what is left of each (nothing should be). Run from the repository root with the venv:
#   bash results/integrity/signals.sh > results/integrity/signals.md
set -u
KB=${KB:-.venv/bin/kgn-bench}
W=$(mktemp -d /tmp/kgn-signals.XXXX)
trials() { [ -f "$1/trials.jsonl" ] && grep -c . "$1/trials.jsonl" || echo 0; }
for sig in TERM KILL; do
  $KB run single_object --detector kgnv2 --trials 2 --workers 2 --quiet --out $W/run_$sig > /dev/null 2>&1 &
  main=$!
  until [ "$(trials $W/run_$sig)" -ge 4 ]; do sleep 0.2; done
  kids=$(pgrep -d, -P $main)  # the two workers and multiprocessing's resource tracker
  kill -$sig $main; wait $main; rc=$?
  sleep 5
  echo "## run, SIG$sig after $(trials $W/run_$sig) trials: exit $rc; children were $kids"
  echo '```'
  ps -o pid,ppid,stat,etime,rss,cmd -p "$kids,$main" | sed "s#$W#W#g"
  echo '```'
  $KB run single_object --detector kgnv2 --trials 2 --workers 2 --quiet --out $W/run_$sig > /dev/null 2>&1
  echo "rerun: exit $?, $(trials $W/run_$sig) trials"
  echo
done
.venv/bin/python -c "import trimesh; trimesh.creation.torus(0.05, 0.015, major_sections=300, minor_sections=60).export('$W/torus.ply')"
$KB objects add $W/torus.ply --name torus_x --root $W/lib > /dev/null 2>&1 &
main=$!
until pgrep -P $main > /dev/null; do sleep 0.1; done
sleep 1
kids=$(pgrep -d, -P $main)
kill -TERM $main; wait $main; rc=$?
sleep 5
echo "## objects add, SIGTERM during CoACD: exit $rc; children were $kids"
echo '```'
ps -o pid,ppid,stat,etime,rss,cmd -p "${kids:-0},$main" | sed "s#$W#W#g"
echo '```'
echo "library folder after: $(ls -A $W/lib 2>/dev/null | tr '\n' ' ')"
rm -rf "$W"

# A benchmark (one pool for a plan) stopped by SIGTERM, and an import killed with SIGKILL during CoACD.
W=$(mktemp -d /tmp/kgn-signals.XXXX)
$KB benchmark --tasks single_object multi_object --detectors oracle --workers 2 --no-viewpoints --runs $W/bm \
  --out $W/bm > /dev/null 2>&1 &
main=$!
until [ "$(cat $W/bm/*/oracle/trials.jsonl 2>/dev/null | grep -c .)" -ge 4 ]; do sleep 0.2; done
kids=$(pgrep -d, -P $main)
kill -TERM $main; wait $main; rc=$?
sleep 5
echo "## benchmark, SIGTERM: exit $rc; children were $kids"
echo '```'
ps -o pid,ppid,stat,etime,rss,cmd -p "$kids,$main" | sed "s#$W#W#g"
echo '```'
.venv/bin/python -c "import trimesh; trimesh.creation.torus(0.05, 0.015, major_sections=300, minor_sections=60).export('$W/torus.ply')"
$KB objects add $W/torus.ply --name torus_x --root $W/lib > /dev/null 2>&1 &
main=$!
until pgrep -P $main > /dev/null; do sleep 0.1; done
sleep 1
kids=$(pgrep -d, -P $main)
kill -KILL $main; wait $main; rc=$?
sleep 5
echo "## objects add, SIGKILL during CoACD: exit $rc; children were $kids"
echo '```'
ps -o pid,ppid,stat,etime,rss,cmd -p "$kids,$main" | sed "s#$W#W#g"
echo '```'
rm -rf "$W"

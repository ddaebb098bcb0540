#!/usr/bin/env bash
# The integrity cases of issue 40, each run as a user would, printed as a Markdown table row:
# case | command | exit | stderr lines | what is left on disk.  Run from the repository root with the venv:
#   bash results/integrity/cases.sh > results/integrity/cases.md
set -u
KB=${KB:-.venv/bin/kgn-bench}
W=$(mktemp -d /tmp/kgn-cases.XXXX)
export KGN_BENCH_OBJECTS=$W/lib
row() {  # name, then the command; stdout/stderr captured
  local name=$1; shift
  "$@" > "$W/out" 2> "$W/err"; local rc=$?
  local lines; lines=$(grep -c . "$W/err")
  printf '| %s | `%s` | %s | %s | %s |\n' "$name" "$(printf "%s" "$*" | tr "\n" "~" | sed "s#$W#W#g; s#|#/#g" | cut -c1-90)" "$rc" "$lines" \
    "$(head -c 150 "$W/err" | tr '\n' ' ' | sed "s#$W#W#g; s#|#/#g")"
}
echo "| case | command | exit | stderr lines | first line |"
echo "|---|---|---:|---:|---|"
printf '[task]\nname = "../../escaped/x"\nprotocol = "single_object"\ntrials = 1\n[objects]\nset = ["cuboid"]\n' > $W/esc.toml
row "task name with ../" $KB run $W/esc.toml --detector oracle --quiet
printf '[task]\nname = "/abs/x"\nprotocol = "single_object"\ntrials = 1\n[objects]\nset = ["cuboid"]\n' > $W/abs.toml
row "absolute task name" $KB run $W/abs.toml --detector oracle --quiet
printf '[task]\nname = "x"\nprotocol = "single_object"\n[objects]\nset = ["/etc/passwd"]\n' > $W/obj.toml
row "object name that is a path" $KB run $W/obj.toml --detector oracle --quiet
mkdir -p $W/lk; echo keep > $W/target; ln -s $W/target $W/lk/.lock
row ".lock planted as a symlink" $KB run ci_oracle --detector oracle --quiet --out $W/lk
echo "target after: $(cat $W/target)" >&2
$KB run ci_oracle --detector oracle --record --quiet --out $W/orc > /dev/null 2>&1
.venv/bin/python - "$W/orc/run.json" <<'PY'
import json, sys; p = sys.argv[1]; d = json.load(open(p)); d["detector"] = "os:abort"; json.dump(d, open(p, "w"))
PY
row "run.json naming os:abort (eval trial)" $KB eval trial $W/orc --trial 0
row "run.json naming os:abort (eval failures)" $KB eval failures $W/orc --quiet
row "replay on port 65535" $KB replay $W/orc --web --port 65535
head -c 300 /dev/urandom > $W/garbage.rrd
row "garbage .rrd" $KB replay $W/garbage.rrd --save $W/copy.rrd
.venv/bin/python -c "import zipfile; z = zipfile.ZipFile('$W/bomb.zip', 'w', zipfile.ZIP_DEFLATED); z.writestr('a.obj', 'v 0 0 0\n' * 2000000); z.close()"
row "zip archive as a mesh" $KB objects add $W/bomb.zip --name bomb
.venv/bin/python -c "import trimesh; trimesh.creation.box((0.04, 0.05, 0.06)).export('$W/box.stl')"
row "name pybullet_test" $KB objects add $W/box.stl --name pybullet_test
row "name pb_mug (shadows a test object)" $KB objects add $W/box.stl --name pb_mug
row "name with a trailing newline" $KB objects add $W/box.stl --name $'box\n'
row "kgnv2_sbranch" $KB run ci_oracle --detector kgnv2_sbranch --quiet --out $W/sb
python3 -m http.server 18765 --bind 127.0.0.1 > /dev/null 2>&1 & HTTP=$!
sleep 1
row "Ray address of an HTTP server" timeout 120 $KB run ci_oracle --detector oracle --backend ray --address 127.0.0.1:18765 --quiet --out $W/ray
kill $HTTP
$KB objects add $W/box.stl --name box_a > /dev/null 2>&1
printf '[task]\nname = "boxes"\nprotocol = "single_object"\ntrials = 2\n[objects]\nset = ["box_a"]\n' > $W/box.toml
.venv/bin/python - "$W/lib/box_a/grasps.npz" <<'PY'
import sys; p = sys.argv[1]; b = open(p, "rb").read(); open(p, "wb").write(b[:200])
PY
row "truncated grasps.npz (run)" $KB run $W/box.toml --detector oracle --quiet --out $W/dmg
row "truncated grasps.npz (objects list)" $KB objects list
echo "left in $W/dmg: $(ls -A $W/dmg 2>/dev/null | tr '\n' ' ')" >&2
rm -rf "$W"

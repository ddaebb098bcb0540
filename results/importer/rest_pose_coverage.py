"""Rest-pose coverage of the verified grasps, before and after the importer spends its checks per rest pose
(issue 44, item 1), on six bones of dm_control's dog model (irregular meshes the project already installs).

For each bone the importer runs as it does now (``objects.coverage``) into a library under OUT; "before" is
the importer's former choice, recomputed: the same seeded candidates, 160 of them spread over grasp directions
only (``diverse_subset``), checked in the same physics, written as a second object ``<name>_before`` with the
grasps that held. Then the oracle runs single-object trials on both (``tasks`` written beside them). Writes
``rest_pose_coverage.md``.

    python results/importer/rest_pose_coverage.py [OUT]      # default runs/rest_pose_coverage
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

import kgn_bench  # noqa: F401  (the portable kernels before numpy's users load)
from kgn_bench.objects.coverage import executable
from kgn_bench.objects.importer import ImportConfig, import_mesh
from kgn_bench.shapes.grasp_sampling import SamplingConfig, diverse_subset, sample_antipodal_grasps
from kgn_bench.shapes.mesh_object import MeshObject
from kgn_bench.sim.grasp_verify import verify_grasps

BONES = {"dog_humerus": "BONEhumerus_L", "dog_femur": "BONEFemoris_L", "dog_radius": "BONERadius_L",
         "dog_scapula": "BONEScapula_L", "dog_tibia": "BONETibia_L", "dog_pelvis": "BONEPelvis"}
TRIALS = 8
HERE = Path(__file__).parent


def main(out: Path) -> None:
    import dm_control

    assets = Path(dm_control.__file__).parent / "suite" / "dog_assets"
    lib = out / "objects"
    rows = []
    for name, stem in BONES.items():
        config = ImportConfig(size=0.16, seed=0, licence="Apache-2.0")
        folder = lib / name
        if not (folder / "object.json").is_file():
            import_mesh(assets / f"{stem}.stl", name, config, root=lib, overwrite=True, preview=False)
        shape = MeshObject(folder)
        m = shape.manifest
        rests = [r["R"] for r in m["rest_poses"]]
        before = lib / f"{name}_before"
        if not (before / "object.json").is_file():
            rng = np.random.default_rng(config.seed)  # the importer's draws up to the candidates
            poses, widths = sample_antipodal_grasps(shape.mesh(), rng, SamplingConfig())
            pick = diverse_subset(poses, config.verify, rng)
            held = verify_grasps(shape, poses[pick], widths[pick])
            shutil.copytree(folder, before)
            np.savez(before / "grasps.npz", poses=poses[pick][held], widths=widths[pick][held])
            mb = json.loads((before / "object.json").read_text())
            mb["name"] = before.name
            for r in mb["rest_poses"]:
                r.pop("grasps", None)
            mb["grasps"] = {"candidates": len(poses), "checked": len(pick), "held": int(held.sum())}
            mb.pop("files_sha256", None)
            (before / "object.json").write_text(json.dumps(mb, indent=1))
        counts = {}
        for tag, f in (("before", before), ("after", folder)):
            g = np.load(f / "grasps.npz")
            counts[tag] = executable(shape.mesh(), rests, g["poses"], g["widths"]).sum(axis=1).tolist()
        rows.append((name, [round(r["probability"], 3) for r in m["rest_poses"]], counts))
    results = {}
    for tag in ("before", "after"):
        task = out / f"coverage_{tag}.toml"
        names = [n + ("_before" if tag == "before" else "") for n in BONES]
        task.write_text(f'[task]\nname = "coverage_{tag}"\nprotocol = "single_object"\nseed = 0\ntrials = {TRIALS}\n'
                        f'[objects]\nset = {json.dumps(names)}\n[camera]\ndistance = 0.8\nelevation_deg = 60.0\n'
                        'azimuth_deg = 90.0\n')
        run = out / f"oracle_{tag}"
        subprocess.run([sys.executable, "-m", "kgn_bench.cli", "run", str(task), "--detector", "oracle", "--workers",
                        "1", "--quiet", "--out", str(run)], check=True, env={**__import__("os").environ,
                                                                              "KGN_BENCH_OBJECTS": str(lib)})
        summary = json.loads((run / "summary.json").read_text())
        results[tag] = summary
    lines = ["# Rest-pose coverage of the verified grasps: six dog bones (dm_control), before and after", "",
             "`python results/importer/rest_pose_coverage.py`. Per rest pose (probability): the verified grasps "
             "the gripper can execute there from above the table (`objects.coverage.executable`), with the "
             "importer's former choice of 160 checks (spread over grasp directions only) and with the current one "
             f"(12 per rest pose first). Then the oracle, {TRIALS} single-object trials an object.", "",
             "| object | rest poses (probability) | executable grasps before | after |", "| --- | --- | --- | --- |"]
    for name, probs, c in rows:
        lines.append(f"| {name} | {probs} | {c['before']} | {c['after']} |")
    lines += ["", "| oracle | success [Wilson 95 %] | failures | per object (k / n) |", "| --- | --- | --- | --- |"]
    for tag, s in results.items():
        r = s["rates"]["success"]
        fails = ", ".join(f"{k} {v}" for k, v in s["failures"].items() if v)
        per = ", ".join(f"{k.removesuffix('_before')} {v['k']}/{v['n']}" for k, v in s["per_object"].items())
        rate = f"{100 * r['rate']:.1f} % [{100 * r['low']:.1f}, {100 * r['high']:.1f}] ({r['k']}/{r['n']})"
        lines.append(f"| {tag} | {rate} | {fails or '-'} | {per} |")
    (HERE / "rest_pose_coverage.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs/rest_pose_coverage"))

"""The tables of results/mesh_detector/README.md from what ``measure.sh`` wrote (issue 44): the real-object
columns, the label-free physics check, Table I on the PS test splits, the same primitive views in four looks, the
fine-tuned candidates, the failures by cause and the dog bones.
Prints Markdown; a missing measurement is a dash.

    python results/mesh_detector/summary.py [RUNS]       # default runs
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from kgn_bench.bench.stats import Rate

DETECTORS = ("kgnv2", "kgnv2_mesh", "antipodal")
COLUMNS = (("single_real", "success", "single"), ("single_real_raw", "success", "single, raw"),
           ("multi_real", "success", "clearance success"), ("multi_real", "clear", "clearance clear"),
           ("multi_real_raw", "success", "clearance success, raw"), ("multi_real_raw", "clear", "clearance clear, raw"),
           ("pile_real", "success", "pile GSR, raw"), ("pile_real", "clear", "pile DR, raw"),
           ("pile_real_assisted", "success", "pile GSR"), ("pile_real_assisted", "clear", "pile DR"),
           ("packed_real", "success", "packed GSR, raw"), ("packed_real", "clear", "packed DR, raw"),
           ("packed_real_assisted", "success", "packed GSR"), ("packed_real_assisted", "clear", "packed DR"))
CAUSES = ("no_grasp", "rotation", "scale", "centre", "position", "width", "moved_by_selector", "execution", "fault")


def _load(path: Path) -> dict | None:
    return json.loads(path.read_text()) if path.is_file() else None


def _rate(cell: dict | None) -> str:
    return str(Rate.from_dict(cell)) if cell and cell.get("n") else "—"


def real_table(report: dict | None) -> str:
    """Rows: detectors; columns: the real-object tasks of ``tasks/benchmark_real.toml``, Wilson intervals."""
    cells: dict[tuple[str, str, str], dict] = {}
    if report:
        for col in report["columns"]:
            for det, row in report["detectors"].items():
                if col["label"] in row:
                    cells[(det, col["task"], col["rate"])] = row[col["label"]]
    lines = []
    for part in (COLUMNS[:6], COLUMNS[6:]):
        lines += ["| detector | " + " | ".join(c[2] for c in part) + " |", "|---" * (len(part) + 1) + "|"]
        for det in DETECTORS:
            lines.append(f"| `{det}` | " + " | ".join(_rate(cells.get((det, t, r))) for t, r, _ in part) + " |")
        lines.append("")
    return "\n".join(lines)


def physics_table(out: Path) -> str:
    lines = ["| model | scenes | predictions checked | held in physics | within 1 cm / 20° of a label |",
             "|---|---|---:|---:|---:|"]
    for det in ("kgnv2", "kgnv2_mesh"):
        for data, label in (("real_multi", "real objects"), ("ps_multi", "primitives")):
            p = _load(out / "physics" / f"{det}_{data}" / "physics.json")
            if p:
                a = p["all"]
                lines.append(f"| `{det}` | {label} | {a['checked']} | {100 * a['held'] / a['checked']:.1f} % "
                             f"({a['held']}) | {100 * a['labelled'] / a['checked']:.1f} % |")
    return "\n".join(lines)


def vision_table(out: Path) -> str:
    lines = ["| model | test split | 1 cm / 20° | 2 cm / 30° | 3 cm / 45° |", "|---|---|---:|---:|---:|"]
    for det in ("kgnv2", "kgnv2_mesh"):
        for data in ("ps_multi", "ps_single"):
            v = _load(out / "vision" / f"{det}_{data}" / "vision.json")
            if v:
                cells = [f"{100 * t['gsr']:.1f} / {100 * t['gcr']:.1f} / {100 * t['osr']:.1f}" for t in v["thresholds"]]
                lines.append(f"| `{det}` | {data} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


LOOKS = (("plain", "plain colours, clean depth (the PS test splits' look)"),
         ("noise", "plain colours, noisy depth"),
         ("texonly", "random textures, clean depth"),
         ("tex", "random textures, noisy depth (kgnv2_mesh's training look)"))


def appearance_table(out: Path) -> str:
    """Both models on the same 240 primitive views in four looks: all shapes at 1 cm / 20° and the two shapes
    where ``kgnv2_mesh`` loses most."""
    lines = ["| model | look | 1 cm / 20°: GSR / GCR / OSR | cuboid GSR | cylinder GSR |", "|---|---|---:|---:|---:|"]
    for det in ("kgnv2", "kgnv2_mesh"):
        for look, label in LOOKS:
            v = _load(out / "appearance" / "eval" / f"{det}_{look}" / "vision.json")
            if v:
                t = v["thresholds"][0]
                shapes = t["per_shape"]
                lines.append(f"| `{det}` | {label} | {100 * t['gsr']:.1f} / {100 * t['gcr']:.1f} / {100 * t['osr']:.1f}"
                             f" | {100 * shapes['cuboid']['gsr']:.1f} | {100 * shapes['cylinder']['gsr']:.1f} |")
    return "\n".join(lines)


def finetune_table(out: Path, runs: Path) -> str:
    """Each fine-tuned candidate of ``finetune.sh`` (a row per run folder under ``finetune/``) beside the shipped
    ``kgnv2_mesh`` and ``kgnv2``: 1 cm / 20° GSR / GCR / OSR on both PS test splits and on textured primitives,
    single real objects, real clearance success / clear, and the physics check on real-object scenes."""
    def vision(path: Path) -> str:
        v = _load(path)
        if not v:
            return "—"
        t = v["thresholds"][0]
        return f"{100 * t['gsr']:.1f} / {100 * t['gcr']:.1f} / {100 * t['osr']:.1f}"

    def physics(path: Path) -> str:
        p = _load(path)
        return f"{100 * p['all']['held'] / p['all']['checked']:.1f} %" if p else "—"

    def rate(summary: dict | None, key: str) -> str:
        return _rate(summary["rates"][key]) if summary else "—"

    lines = ["| model | PS multi | PS single | textured primitives | single real | clearance success | clearance clear "
             "| physics, real scenes |", "|---" * 8 + "|"]
    for det in ("kgnv2", "kgnv2_mesh"):
        single, multi = _load(runs / "real" / "single_real" / det / "summary.json"), \
            _load(runs / "real" / "multi_real" / det / "summary.json")
        lines.append(f"| `{det}` (shipped) | {vision(out / 'vision' / f'{det}_ps_multi' / 'vision.json')} | "
                     f"{vision(out / 'vision' / f'{det}_ps_single' / 'vision.json')} | "
                     f"{vision(out / 'appearance' / 'eval' / f'{det}_tex' / 'vision.json')} | "
                     f"{rate(single, 'success')} | {rate(multi, 'success')} | {rate(multi, 'clear')} | "
                     f"{physics(out / 'physics' / f'{det}_real_multi' / 'physics.json')} |")
    for f in sorted((out / "finetune").glob("*")) if (out / "finetune").is_dir() else []:
        single, multi = _load(f / "single_real" / "summary.json"), _load(f / "multi_real" / "summary.json")
        lines.append(f"| `{f.name}` | {vision(f / 'vision_ps_multi' / 'vision.json')} | "
                     f"{vision(f / 'vision_ps_single' / 'vision.json')} | {vision(f / 'look_tex' / 'vision.json')} | "
                     f"{rate(single, 'success')} | {rate(multi, 'success')} | {rate(multi, 'clear')} | "
                     f"{physics(f / 'physics_real' / 'physics.json')} |")
    return "\n".join(lines)


def failures_table(out: Path) -> str:
    lines = ["| detector | failed / attempts | " + " | ".join(CAUSES) + " |", "|---" * (len(CAUSES) + 2) + "|"]
    for det in DETECTORS:
        f = _load(out / "failures" / det / "failures.json")
        if f:
            failed = sum(f["counts"].values())
            lines.append(f"| `{det}` | {failed} / {f['attempts']} | "
                         + " | ".join(str(f["counts"].get(c, 0)) for c in CAUSES) + " |")
    return "\n".join(lines)


def dog_table(runs: Path) -> str:
    lines = ["| detector | success | failures | per object (k / n) |", "|---|---|---|---|"]
    for det in (*DETECTORS, "oracle"):
        s = _load(runs / "dog" / det / "summary.json")
        if s:
            fails = ", ".join(f"{k} {v}" for k, v in s["failures"].items() if v)
            per = ", ".join(f"{o} {c['k']}/{c['n']}" for o, c in sorted(s["per_object"].items()))
            lines.append(f"| `{det}` | {_rate(s['rates']['success'])} | {fails or '—'} | {per} |")
    return "\n".join(lines)


def main(runs: Path) -> None:
    out = runs / "mesh_detector"
    print("## Real objects\n\n" + real_table(_load(out / "real_report" / "benchmark.json")))
    print("## The label-free physics check\n\n" + physics_table(out) + "\n")
    print("## Table I on the PS test splits (GSR / GCR / OSR %)\n\n" + vision_table(out) + "\n")
    print("## The same primitive views in four looks (240 views, 1 cm / 20°, %)\n\n" + appearance_table(out) + "\n")
    print("## Fine-tuned candidates (1 cm / 20° for the vision columns)\n\n" + finetune_table(out, runs) + "\n")
    print("## Failed single-object attempts by cause\n\n" + failures_table(out) + "\n")
    print("## Six meshes from a source in neither split (dm_control's dog bones)\n\n" + dog_table(runs))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs"))

"""Draw the import graph of kgn_bench's units (subpackages and root modules) on their layers, as
tests/test_layers.py reads it (every import, lazy ones included), into import_graph.png and import_graph.md.

    .venv/bin/python results/architecture/import_graph.py                          # this checkout
    .venv/bin/python results/architecture/import_graph.py OLD/kgn_bench before     # another tree -> before.png/.md

Units of an older tree that the layers no longer name (the root ``perf`` module) are drawn on the layer their
code moved to.
"""

import importlib.util
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
spec = importlib.util.spec_from_file_location("test_layers", ROOT / "tests" / "test_layers.py")
layers = importlib.util.module_from_spec(spec)
sys.modules["test_layers"] = layers
spec.loader.exec_module(layers)


MOVED = {"perf": "bench"}


def main(package: Path = ROOT / "kgn_bench", stem: str = "import_graph") -> None:
    for old, new in MOVED.items():
        layers.LAYER.setdefault(old, layers.LAYER[new])
    graph = layers.unit_graph(layers.all_imports(package))
    subpackages = sorted(p.name for p in package.iterdir() if p.is_dir() and p.name != "__pycache__")
    lines = ["# Import graph of kgn_bench's subpackages", "",
             "Read by `tests/test_layers.py` (every import, lazy ones included); made by",
             "`.venv/bin/python results/architecture/import_graph.py`. Layers, lowest first: "
             + " < ".join("/".join(u) if len(u) < 4 else "foundation" for u in layers.LAYERS) + ".", "",
             "| subpackage | layer | imports (subpackages) |", "|---|---|---|"]
    for name in sorted(subpackages, key=lambda u: layers.LAYER[u]):
        deps = sorted((d for d in graph.get(name, ()) if d in subpackages), key=lambda u: layers.LAYER[u])
        lines.append(f"| {name} | {layers.LAYER[name]} | {', '.join(deps) or '-'} |")
    cycle = layers.find_cycle({u: {d for d in graph.get(u, ()) if d in subpackages} for u in subpackages})
    lines += ["", f"Cycle between subpackages: {cycle or 'none'}.", ""]
    (HERE / f"{stem}.md").write_text("\n".join(lines))

    units = ["foundation", "types", "shapes", "config", *[u for u in subpackages if layers.LAYER[u] > 3], "cli"]
    units += [u for u in graph if u in MOVED]
    units = sorted(dict.fromkeys(units), key=lambda u: 0 if u == "foundation" else layers.LAYER[u])

    def group(d: str) -> str:
        return "foundation" if layers.LAYER.get(d, 0) == 0 else d

    n = len(units)
    up = 0
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    ax.add_patch(plt.Polygon([(-0.5, -0.5), (n - 0.5, -0.5), (n - 0.5, n - 0.5)], color="#fbe3e3", zorder=0))
    for i, u in enumerate(units):
        members = list(layers.LAYERS[0]) if u == "foundation" else [u]
        for d in {group(d) for m in members for d in graph.get(m, ())} - {u}:
            j = units.index(d)
            ax.plot(j, i, "s", ms=14, color="#2f6db5" if j < i else "#c0392b")
            up += j > i
    ax.set_xticks(range(n), units, rotation=60, ha="right")
    ax.set_yticks(range(n), units)
    ax.set_xlim(-0.5, n - 0.5)
    ax.set_ylim(n - 0.5, -0.5)
    ax.set_xlabel("imported unit (lower layers to the left)")
    ax.set_ylabel("unit, by layer")
    ax.grid(color="0.9")
    verdict = (f"{up} unit pairs import up the layers (red)" if up else "every mark below the diagonal")
    ax.set_title(f"kgn_bench's import graph ({stem.replace('_', ' ')}): {verdict}\n"
                 "(an import up the layers falls in the red triangle)", fontsize=10)
    fig.tight_layout()
    fig.savefig(HERE / f"{stem}.png", dpi=110)
    print("\n".join(lines))


if __name__ == "__main__":
    main(*(([Path(sys.argv[1]), sys.argv[2]]) if len(sys.argv) > 2 else []))

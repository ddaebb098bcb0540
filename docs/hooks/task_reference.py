"""MkDocs hook: the task-file reference, generated at build time from ``kgn_bench.config``'s dataclasses.

``docs/task-file.md`` holds the prose and the marker ``<!-- task-file-reference -->``; ``on_page_markdown``
replaces the marker with one table per task-file section: every field of the section's dataclass with its
TOML key, its type and default (``dataclasses.fields``) and its meaning. The meaning is, in this order, the
field's own docstring (a string right after it in the class body), the sentences of the class docstring that
name it, and else a note of ``NOTES`` below. A field added to a config therefore appears in the reference by
itself; a note for a field that no longer exists fails the build (``reference_markdown``).
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import itertools
import re
import textwrap
import typing

from kgn_bench import config

MARKER = "<!-- task-file-reference -->"
PAGE = "task-file.md"

# TOML section -> (its dataclass, {TOML key: field name} where the two differ).
SECTIONS: tuple[tuple[str, type, dict[str, str]], ...] = (
    ("task", config.TaskConfig, {}),
    ("objects", config.TaskConfig, {"set": "objects", "per_scene": "objects_per_scene"}),
    ("camera", config.CameraConfig, {}),
    ("selector", config.SelectorConfig, {}),
    ("execution", config.ExecutionConfig, {}),
    ("resources", config.ResourceConfig, {}),
)
OBJECT_FIELDS = ("objects", "objects_per_scene")
NESTED = ("camera", "selector", "execution", "resources")

# Meanings of the fields whose class docstring does not name them (the code that reads each is named).
NOTES: dict[tuple[str, str], str] = {
    ("TaskConfig", "name"): "The task's name; it names the run folder, so letters, digits and `_ . -` only.",
    ("TaskConfig", "protocol"): "What a trial is (see Protocols and metrics).",
    ("TaskConfig", "seed"): "The run's seed: trial i's scene comes from `default_rng([seed, i])`, so every "
                            "detector sees the same scenes.",
    ("TaskConfig", "objects_per_scene"): "Objects placed in each scene of a round of several objects.",
    ("TaskConfig", "objects"): "Object names (built-in types, imported or packaged objects), or the name of a "
                               "packaged set such as `\"pybullet_test\"`.",
    ("SelectorConfig", "max_candidates"): "At most this many of the best-scored candidates are checked.",
    ("SelectorConfig", "collision_points"): "A gripper box holding this many observed points or more collides.",
    ("SelectorConfig", "enclosed_points"): "At least this many observed points must lie between the fingers.",
    ("SelectorConfig", "table_clearance"): "How far (m) the gripper must stay above the table top.",
    ("SelectorConfig", "point_stride"): "Pixel stride of the depth image when the observed cloud is "
                                        "back-projected for the checks.",
    ("SelectorConfig", "approach_search"): "Pose search: how far (m) a candidate may be shifted along its approach.",
    ("SelectorConfig", "closing_search"): "Pose search: how far (m) a candidate may be shifted along its closing "
                                          "axis.",
    ("SelectorConfig", "search_step"): "Pose search: the step (m) of those shifts, nearest first.",
    ("ExecutionConfig", "pregrasp_distance"): "The pre-grasp stands this far (m) back along the approach.",
    ("ExecutionConfig", "approach_time"): "Duration (s) of the straight moves to the pre-grasp and the grasp.",
    ("ExecutionConfig", "lift_height"): "How high (m) the grasped object is lifted.",
    ("ExecutionConfig", "min_lift"): "The object must rise at least this much (m) with the gripper, else "
                                     "`dropped_lift`.",
    ("ExecutionConfig", "max_consecutive_failures"): "A round of several objects ends after this many failed "
                                                     "attempts in a row.",
    ("ExecutionConfig", "max_attempts_per_object"): "A round of several objects makes at most this many "
                                                    "attempts per object placed.",
    ("ExecutionConfig", "settle_time"): "Wait (s) for the scene to settle after the lift and after an attempt.",
}
ALLOWED = {("TaskConfig", "protocol"): config.PROTOCOLS, ("SelectorConfig", "mode"): config.SELECTOR_MODES,
           ("SelectorConfig", "score"): config.SCORES}


def config_classes() -> list[type]:
    """Every dataclass defined in ``kgn_bench.config``, in source order."""
    found = [c for _, c in inspect.getmembers(config, inspect.isclass)
             if dataclasses.is_dataclass(c) and c.__module__ == config.__name__]
    return sorted(found, key=lambda c: inspect.getsourcelines(c)[1])


def attribute_docs(cls: type) -> dict[str, str]:
    """Field name -> the string literal that follows the field's annotated assignment in ``cls``'s body."""
    body = ast.parse(textwrap.dedent(inspect.getsource(cls))).body[0].body
    out = {}
    for stmt, nxt in itertools.pairwise(body):
        if (isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) and isinstance(nxt, ast.Expr)
                and isinstance(nxt.value, ast.Constant) and isinstance(nxt.value.value, str)):
            out[stmt.target.id] = " ".join(nxt.value.value.split())
    return out


def _sentences(doc: str) -> list[str]:
    return re.split(r"(?<=[.])\s+(?=[A-Z`])", " ".join(doc.split()))


def meaning(cls: type, name: str) -> str:
    """The documented meaning of field ``name`` of ``cls`` (module docstring: the order of the sources)."""
    own = attribute_docs(cls).get(name)
    if own:
        text = own
    else:
        mentioned = [s for s in _sentences(inspect.getdoc(cls) or "") if f"``{name}``" in s]
        text = " ".join([NOTES.get((cls.__name__, name), ""), *mentioned]).strip()
    if not text and cls is config.TaskConfig and name in NESTED:
        section = typing.get_type_hints(cls)[name]
        text = (" ".join((inspect.getdoc(section) or "").split()).split(". ")[0] + ".").replace("``", "`")
    allowed = ALLOWED.get((cls.__name__, name))
    if allowed:
        text = f"{text} One of: {', '.join(f'``{v}``' for v in allowed)}.".strip()
    return text.replace("``", "`")


def default_text(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        value = f.default
    elif f.default_factory is not dataclasses.MISSING:
        value = f.default_factory()
    else:
        return "required"
    if dataclasses.is_dataclass(value):
        return f"the `[{f.name}]` section below"
    if isinstance(value, tuple) and all(isinstance(v, str) for v in value):
        return "[" + ", ".join(f'"{v}"' for v in value) + "]"
    return f"`{value!r}`".replace("True", "true").replace("False", "false")


def _cell(text: str) -> str:
    return text.replace("|", "&#124;").replace("\n", " ")


def section_table(section: str, cls: type, keys: dict[str, str]) -> list[str]:
    by_field = {v: k for k, v in keys.items()}
    wanted = [f for f in dataclasses.fields(cls)
              if (section == "objects") == (f.name in OBJECT_FIELDS) or cls is not config.TaskConfig]
    doc = " ".join((inspect.getdoc(cls) or "").split()).replace("``", "`")
    lines = [f"### `[{section}]`", "", f"Dataclass `kgn_bench.config.{cls.__name__}`: {doc}", "",
             "| key | field | type | default | meaning |", "|---|---|---|---|---|"]
    for f in wanted:
        key = f"[{f.name}]" if f.name in NESTED and cls is config.TaskConfig else by_field.get(f.name, f.name)
        kind = str(f.type) + (" (a number, or `[lo, hi]` drawn per trial)" if f.type == "Span" else "")
        lines.append(f"| `{key}` | `{f.name}` | {_cell(kind)} | {_cell(default_text(f))} | "
                     f"{_cell(meaning(cls, f.name))} |")
    return [*lines, ""]


def reference_markdown() -> str:
    """The generated reference: one table per section, every field of every config dataclass once."""
    names = {(c.__name__, f.name) for c in config_classes() for f in dataclasses.fields(c)}
    stale = sorted(set(NOTES) - names)
    if stale:
        raise ValueError(f"docs/hooks/task_reference.py: NOTES names fields that do not exist: {stale}")
    covered = {cls for _, cls, _ in SECTIONS}
    missing = [c.__name__ for c in config_classes() if c not in covered]
    if missing:
        raise ValueError(f"docs/hooks/task_reference.py: no task-file section for {missing}; add it to SECTIONS")
    lines: list[str] = []
    for section, cls, keys in SECTIONS:
        lines += section_table(section, cls, keys)
    return "\n".join(lines)


def on_page_markdown(markdown, page, config, files):
    if page.file.src_uri == PAGE:
        if MARKER not in markdown:
            raise ValueError(f"docs/{PAGE} lost its marker {MARKER}")
        return markdown.replace(MARKER, reference_markdown())
    return markdown

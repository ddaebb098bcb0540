"""Why a closed-loop attempt went the way it did: its capture re-created, and the detector's chosen grasp
measured against the true grasps of the objects on the table.

``explain_trial(run, index, attempt)`` reads the run folder's ``run.json`` (task config, detector, seed) and
trial ``index``'s record, re-creates the trial up to the selection of attempt ``attempt`` (``bench.trial.capture``:
the same scene, camera, depth noise, detector seed and selector, the earlier attempts executed as in the run)
and splits two poses' error against their nearest true
grasp into the terms the network predicts separately (``eval.errors.grasp_errors``: centre in the image
plane, distance along the camera ray, rotation, width):

* the **candidate**: the chosen candidate as the detector predicted it (world frame ``T_world_grasp``, after
  levelling in assisted mode: ``Selection.candidate``);
* the **executed** grasp: where the selector sent the gripper (``Selection.grasp``: after the pose search and
  the centring, and in the symmetric form the arm reaches).

The true grasps are ``detectors.oracle.true_grasps`` of every object on the table: the labelled families with
their ±30° tilts, minus those whose labelling proxy collides. A candidate "matches" when it lies within 1 cm and
20° of one (the vision metrics' first threshold). So a failed trial reads as one of: the detector's pose was
off (rotation, or the centre in the image), its scale was off (the distance along the ray), its width was off,
or the pose was right and what followed (the selector, the arm, the physics) lost it.

The re-created earlier attempts and selection are compared with the record; a learned detector whose weights
changed since the run (``weights_sha256``) is named in the result, since its candidates then differ.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kgn_bench.bench.records import TrialRecord
from kgn_bench.config import ConfigError, task_from_dict
from kgn_bench.errors import KGNBenchError
from kgn_bench.geometry import invert_pose
from kgn_bench.grasp import GraspSet
from kgn_bench.io import atomic_write_text

from .errors import TERMS, grasp_errors

__all__ = ["CATEGORIES", "ExplainError", "FailureStudy", "GraspError", "TrialExplanation", "category",
           "explain_failures", "explain_trial", "failures_markdown", "markdown", "write_explanation", "write_failures"]

TOP = 10
"""How many of the best-scored candidates the explanation checks against the true grasps (and draws)."""
SHOWN_TRUTH = 40
"""At most this many true grasps are drawn (evenly through the set)."""
ZOOM = 2.5
"""Largest magnification of the image's right half about the executed grasp."""


class ExplainError(KGNBenchError):
    """A run folder or trial that cannot be explained (no run.json, no such trial, a scene that cannot be built)."""


@dataclass(frozen=True)
class GraspError:
    """One grasp's error against its nearest true grasp: ``centre_px`` (px) and ``centre_cm`` (the same in cm at
    the true grasp's depth), ``ray_cm`` (distance from the camera, predicted − true; negative = short of it),
    ``rotation_deg`` (symmetric geodesic angle), ``width_cm`` (predicted − true), and ``matched`` (within 1 cm
    and 20° of a true grasp)."""

    centre_px: float
    centre_cm: float
    ray_cm: float
    rotation_deg: float
    width_cm: float
    matched: bool


@dataclass
class TrialExplanation:
    """Attempt ``attempt`` of trial ``index`` of the run in ``run``: the trial's ``objects``, the recorded
    attempt (``recorded``: reason, detail, selected candidate), and the re-created one: ``candidates`` (count),
    ``selected`` (index or None), the selector's ``rejected`` counts, the ``candidate`` and ``executed`` errors
    (None when nothing was selected), ``top_matched`` (how many of the ``TOP`` best-scored candidates match a
    true grasp) and ``matched`` (how many of all). ``same_as_recorded``: the re-created earlier attempts and
    selection are the recorded ones. ``image``: the camera view twice, with true grasps (green) on the left,
    and on the right the best-scored candidates (yellow), the executed grasp (red) and its nearest true grasp
    (magenta), magnified."""

    run: str
    task: str
    detector: str
    index: int
    attempt: int
    objects: list[str]
    recorded: dict[str, Any]
    candidates: int
    selected: int | None
    rejected: dict[str, int]
    candidate: GraspError | None
    executed: GraspError | None
    top_matched: int
    top: int
    matched: int
    same_as_recorded: bool
    weights_changed: bool = False
    image: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), np.uint8), repr=False)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        del out["image"]
        return out


def _read_run(run: Path) -> dict[str, Any]:
    path = run / "run.json"
    try:
        identity = json.loads(path.read_text())
    except FileNotFoundError:
        raise ExplainError(f"{run}: not a run folder (no run.json)") from None
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ExplainError(f"{path}: unreadable ({type(e).__name__})") from None
    if not isinstance(identity, dict) or not {"detector", "config"} <= identity.keys():
        raise ExplainError(f"{path}: not a run's identity (needs detector and config)")
    return identity


def _grasp_error(row: np.ndarray, matched: bool) -> GraspError:
    values = dict(zip(TERMS, (round(float(v), 2) for v in row), strict=True))
    return GraspError(**values, matched=bool(matched))


def _zoom(img: np.ndarray, box: np.ndarray, most: float) -> np.ndarray:
    """``img`` magnified about the pixel box ``(u0, v0, u1, v1)`` so that the box with a 30 % margin fills it,
    at most ``most`` times (the window kept inside the image)."""
    import cv2

    h, w = img.shape[:2]
    bw, bh = 1.6 * max(box[2] - box[0], 1.0), 1.6 * max(box[3] - box[1], 1.0)
    factor = float(np.clip(min(w / bw, h / bh), 1.0, most))
    cw, ch = int(w / factor), int(h / factor)
    x0 = int(np.clip((box[0] + box[2] - cw) / 2, 0, w - cw))
    y0 = int(np.clip((box[1] + box[3] - ch) / 2, 0, h - ch))
    return cv2.resize(img[y0:y0 + ch, x0:x0 + cw], (w, h), interpolation=cv2.INTER_LINEAR)


def _draw(obs, truth: GraspSet, best: np.ndarray, best_widths: np.ndarray, executed: np.ndarray | None,
          executed_width: float, nearest: np.ndarray | None) -> np.ndarray:
    """Left: the camera view with at most ``SHOWN_TRUTH`` true grasps (green). Right: the best-scored candidates
    (yellow), the executed grasp (red) and its nearest true grasp (magenta), magnified (at most ``ZOOM`` times)
    about these two (or the best candidate). Boxes have the grasp's width."""
    from kgn_bench.geometry import project
    from kgn_bench.grasp import keypoints_in_frame
    from kgn_bench.viz.draw import draw_grasps

    T_cam_world = invert_pose(obs.camera_pose)
    K = obs.intrinsics.K
    shown = np.linspace(0, len(truth) - 1, min(len(truth), SHOWN_TRUTH)).astype(int) if len(truth) else []
    left = draw_grasps(obs.rgb, T_cam_world @ truth.poses[shown], np.maximum(truth.widths[shown], 0.01), K,
                       (0, 170, 0))
    right = draw_grasps(obs.rgb, T_cam_world @ best, np.maximum(best_widths, 0.01), K, (255, 200, 0))
    if nearest is not None:
        right = draw_grasps(right, (T_cam_world @ truth.poses[nearest])[None],
                            np.array([max(truth.widths[nearest], 0.01)]), K, (255, 0, 255), 2)
    if executed is not None:
        right = draw_grasps(right, (T_cam_world @ executed)[None], np.array([max(executed_width, 0.01)]), K,
                            (255, 0, 0), 2)
    focus = [(executed, executed_width)] if executed is not None else [(best[0], best_widths[0])] if len(best) else []
    if nearest is not None:
        focus.append((truth.poses[nearest], truth.widths[nearest]))
    if focus:
        poses = T_cam_world @ np.stack([f[0] for f in focus])
        kpts = keypoints_in_frame(poses, np.maximum([f[1] for f in focus], 0.01)).reshape(-1, 3)
        kpts = np.concatenate([kpts, poses[:, :3, 3]])
        if (kpts[:, 2] > 1e-3).all():
            uv = project(kpts, K)
            right = _zoom(right, np.r_[uv.min(axis=0), uv.max(axis=0)], ZOOM)
    return np.concatenate([left, right], axis=1)


@dataclass
class _Run:
    """A run folder opened for explanations: its task, detector (built once) and trial records by index."""

    path: Path
    task: Any
    detector_name: str
    detector: Any
    weights_changed: bool
    records: dict[int, TrialRecord]


def _trusted_detector(run: Path, recorded: Any, given: str | None) -> str:
    """The detector to build for a run folder: a registered name as recorded; a ``module:attribute`` one only
    when the command line names it too (``given``), since a run folder is data and must not make the tool
    import code named inside it."""
    from kgn_bench.detectors import DETECTORS

    if not isinstance(recorded, str):
        raise ExplainError(f"{run / 'run.json'}: the detector must be a name, got {recorded!r}")
    if given is not None and given != recorded:
        raise ExplainError(f"{run}: ran detector {recorded!r}, not {given!r}")
    if recorded not in DETECTORS and given is None:
        raise ExplainError(f"{run}: its detector {recorded!r} is code outside kgn-bench; a run folder does not "
                           f"choose code to run, so name it yourself: --detector {recorded}")
    return recorded


def _open_run(run: str | Path, detector: str | None = None) -> _Run:
    from kgn_bench.bench.runner import build_detector, read_trials, run_identity

    run = Path(run)
    identity = _read_run(run)
    try:
        task = task_from_dict(identity["config"], f"{run / 'run.json'} config")
    except ConfigError as e:
        raise ExplainError(str(e)) from None
    name = _trusted_detector(run, identity["detector"], detector)
    records = {r.index: r for r in read_trials(run / "trials.jsonl", repair=False)  # a reader: never writes
               if isinstance(r.index, int)}
    detector = build_detector(name)
    changed = run_identity(task, name).get("weights_sha256") != identity.get("weights_sha256")
    return _Run(run, task, name, detector, changed, records)


def _explain(r: _Run, index: int, attempt: int, top: int, draw: bool) -> TrialExplanation:
    """Attempt ``attempt`` of trial ``index`` of the opened run (its record exists and has that attempt)."""
    from kgn_bench.bench.trial import capture
    from kgn_bench.detectors.base import DetectorError
    from kgn_bench.detectors.oracle import true_grasps
    from kgn_bench.sim.control import IK
    from kgn_bench.sim.robot import on_table
    from kgn_bench.sim.scene import PhysicsError
    from kgn_bench.threads import trial_threads

    record = r.records[index]
    attempts = record.attempts
    with trial_threads():
        try:
            cap = capture(r.task, index, r.detector, IK(), attempt)
        except PhysicsError as e:
            raise ExplainError(f"{r.path}: trial {index}: no stable scene ({e})") from None
        except DetectorError as e:
            raise ExplainError(f"{r.path}: trial {index}: the detector failed ({e})") from None
    if cap is None:
        raise ExplainError(f"{r.path}: trial {index} ended before attempt {attempt} when re-created, unlike the "
                           "record (another machine or package version?)")
    scene, obs, cands, sel = cap.scene, cap.observation, cap.candidates, cap.selection
    on = [i for i in range(len(scene.objects)) if on_table(scene, i)]
    truth = GraspSet.concatenate([true_grasps(scene, i) for i in on]) if on else GraspSet.empty()
    world = cands.world_poses(obs.camera_pose)

    candidate = executed = nearest = None
    if sel.index is not None and len(truth):
        rows, matched, near = grasp_errors(np.stack([sel.candidate, sel.grasp]),
                                           np.array([cands.widths[sel.index], cands.widths[sel.index]]), truth, obs)
        candidate, executed, nearest = _grasp_error(rows[0], matched[0]), _grasp_error(rows[1], matched[1]), near[1]
    all_matched = np.zeros(len(world), dtype=bool)
    if len(world) and len(truth):
        all_matched = grasp_errors(world, cands.widths, truth, obs)[1]
    best = np.argsort(-sel.scores, kind="stable")[:top]
    mine = attempts[attempt - 1]
    recorded = {k: getattr(mine, k) for k in ("success", "reason", "detail", "candidates", "selected")}
    same = (cap.earlier == attempts[: attempt - 1] and sel.index == mine.selected
            and len(cands) == mine.candidates)
    image = _draw(obs, truth, world[best], cands.widths[best], sel.grasp, sel.width, nearest) if draw else None
    return TrialExplanation(
        run=str(r.path), task=r.task.name, detector=r.detector_name, index=index, attempt=attempt,
        objects=list(record.objects),
        recorded=recorded, candidates=len(cands), selected=sel.index, rejected=dict(sel.rejected),
        candidate=candidate, executed=executed, top_matched=int(all_matched[best].sum()), top=len(best),
        matched=int(all_matched.sum()), same_as_recorded=same, weights_changed=r.weights_changed,
        **({"image": image} if image is not None else {}))


def explain_trial(run: str | Path, index: int, attempt: int = 1, top: int = TOP,
                  detector: str | None = None) -> TrialExplanation:
    """Re-create trial ``index`` of the run folder ``run`` up to the selection of its attempt ``attempt`` (1 = the
    first) and measure the chosen grasp against the true grasps (module docstring). ``ExplainError`` (one line)
    for a folder that is not a run, a trial or attempt without a record, or a scene or detector that fails.
    A run of a ``module:attribute`` detector needs that name as ``detector`` (a run folder names no code to
    import on its own)."""
    run = Path(run)
    r = _open_run(run, detector)
    if not 0 <= index < r.task.n_trials:
        raise ExplainError(f"{run}: trial {index} is out of range (the run has trials 0-{r.task.n_trials - 1})")
    if index not in r.records:
        raise ExplainError(f"{run}: trial {index} has no record in trials.jsonl (run or resume it first)")
    attempts = r.records[index].attempts
    if not 1 <= attempt <= len(attempts):
        raise ExplainError(f"{run}: trial {index} has no attempt {attempt} (it made {len(attempts)})")
    return _explain(r, index, attempt, top, draw=True)


CATEGORIES = ("no_grasp", "no_truth", "rotation", "scale", "centre", "position", "width", "moved_by_selector",
              "execution", "fault")
"""Why a failed attempt failed, by the first rule that holds (``category``)."""


def category(x: TrialExplanation) -> str:
    """The failure's category, by the first rule that holds, on the candidate as predicted (``TERMS``' limits
    of the (1 cm, 20°) match):

    ``no_grasp``: no candidate passed the selector; ``no_truth``: one did, but no object on the table has a
    collision-free true grasp to measure it against (wedged in a pile); ``rotation``: ≥ 20° from its nearest true grasp;
    ``scale``: ≥ 1 cm off along the camera ray; ``centre``: ≥ 1 cm off in the image plane; ``position``: not
    within 1 cm of a true grasp although each term is; ``width``: a match, with the width ≥ 1 cm off;
    ``moved_by_selector``: a match that the selector's shifts moved out of it; ``execution``: a match executed
    as a match (what failed is the arm, the physics, or the true grasp's own limits)."""
    c, e = x.candidate, x.executed
    if x.selected is None:
        return "no_grasp"
    if c is None or e is None:
        return "no_truth"
    if not c.matched:
        if c.rotation_deg >= 20.0:
            return "rotation"
        if abs(c.ray_cm) >= 1.0:
            return "scale"
        return "centre" if c.centre_cm >= 1.0 else "position"
    if abs(c.width_cm) >= 1.0:
        return "width"
    return "execution" if e.matched else "moved_by_selector"


@dataclass
class FailureStudy:
    """Every failed attempt of a run explained (``explanations``, each with its ``category``), and the attempts
    that were faults, not grasps (``faults``: ``physics_error`` and ``detector_error``, not re-created)."""

    run: str
    detector: str
    task: str
    attempts: int
    explanations: list[TrialExplanation]
    faults: list[dict[str, Any]]
    trials: int = 0
    """Trials with a record (the run's finished ones)."""
    planned: int = 0
    """Trials the run has in all; more than ``trials`` for an unfinished run."""

    def counts(self) -> dict[str, int]:
        out = dict.fromkeys(CATEGORIES, 0)
        for x in self.explanations:
            out[category(x)] += 1
        out["fault"] = len(self.faults)
        return out


def explain_failures(run: str | Path, top: int = TOP, progress: bool = True,
                     detector: str | None = None) -> FailureStudy:
    """Explain every failed attempt of the run folder ``run`` (``explain_trial`` without the images); a
    ``physics_error`` or ``detector_error`` attempt is listed as a fault. A clearance round's later attempt is
    re-created after its earlier ones, so a run of many rounds takes a while (a progress bar shows it)."""
    from kgn_bench.progress import Progress

    r = _open_run(run, detector)
    todo, faults, total = [], [], 0
    for index in sorted(r.records):
        for k, a in enumerate(r.records[index].attempts, start=1):
            total += 1
            if a.success:
                continue
            if a.reason in ("physics_error", "detector_error"):
                faults.append({"index": index, "attempt": k, "reason": a.reason, "detail": a.detail})
            else:
                todo.append((index, k))
    bar = Progress(len(todo), f"explain {r.detector_name} failures", unit="attempts", enabled=progress)
    explanations = []
    for index, k in todo:
        explanations.append(_explain(r, index, k, top, draw=False))
        bar.update()
    bar.close()
    return FailureStudy(str(r.path), r.detector_name, r.task.name, total, explanations, faults,
                        trials=len(r.records), planned=r.task.n_trials)


def _row(label: str, e: GraspError | None) -> str:
    if e is None:
        return f"| {label} | – | – | – | – | – |"
    return (f"| {label} | {e.centre_cm:.2f} | {e.ray_cm:+.2f} | {e.rotation_deg:.1f} | {e.width_cm:+.2f} | "
            f"{'yes' if e.matched else 'no'} |")


def markdown(x: TrialExplanation) -> str:
    """The explanation as a short Markdown report."""
    rec = x.recorded
    outcome = "success" if rec.get("success") else f"{rec.get('reason')}" + (f" ({rec['detail']})" if rec.get("detail")
                                                                              else "")
    rejected = ", ".join(f"{k} {v}" for k, v in x.rejected.items() if v) or "none"
    lines = [
        f"# Trial {x.index}, attempt {x.attempt} of {x.run}",
        "",
        f"Task {x.task}, detector {x.detector}, objects: {', '.join(x.objects)}.",
        f"Recorded: {outcome}; candidate {rec.get('selected')} of {rec.get('candidates')}.",
        f"Re-created: candidate {x.selected} of {x.candidates} selected (rejected: {rejected})"
        + ("." if x.same_as_recorded else "; NOT as recorded (earlier attempts or this selection differ)."),
    ]
    if x.weights_changed:
        lines.append("The detector's weights are not those of the run: its candidates differ.")
    lines += [
        "",
        "Error against the nearest true grasp (cm, degrees; ray: predicted − true distance from the camera):",
        "",
        "| grasp | centre (image plane) | along the ray | rotation | width | within 1 cm, 20° |",
        "|---|---:|---:|---:|---:|---|",
        _row("candidate (as predicted)", x.candidate),
        _row("executed (after the selector)", x.executed),
        "",
        f"Candidates within 1 cm and 20° of a true grasp: {x.top_matched} of the {x.top} best-scored, "
        f"{x.matched} of all {x.candidates}.",
        "",
    ]
    return "\n".join(lines)


def write_explanation(x: TrialExplanation, out: str | Path) -> list[Path]:
    """``explain.json``, ``explain.md`` and ``explain.png`` in folder ``out``, each written atomically."""
    from kgn_bench.viz.images import save_png

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "explain.json", out / "explain.md", out / "explain.png"]
    atomic_write_text(paths[0], json.dumps(x.to_dict(), indent=2) + "\n")
    atomic_write_text(paths[1], markdown(x))
    save_png(paths[2], x.image)
    return paths


_CATEGORY_TEXT = {
    "no_grasp": "no candidate passed the selector",
    "no_truth": "no true grasp left to measure against",
    "rotation": "rotation ≥ 20° off",
    "scale": "≥ 1 cm off along the ray (scale)",
    "centre": "≥ 1 cm off in the image plane",
    "position": "≥ 1 cm off in 3-D, each term under its limit",
    "width": "pose right, width ≥ 1 cm off",
    "moved_by_selector": "pose right, moved off it by the selector",
    "execution": "pose right and executed right",
    "fault": "a fault, not a grasp (physics_error, detector_error)",
}


def failures_markdown(study: FailureStudy) -> str:
    """The study as Markdown: the counts per category, then one row per failed attempt."""
    n = len(study.explanations) + len(study.faults)
    lines = [f"# Failed attempts of {study.run}", "",
             f"Task {study.task}, detector {study.detector}: {n} of {study.attempts} attempts failed. Each is "
             "re-created and its chosen candidate measured against the true grasps (`kgn-bench eval trial`); "
             "the category is the first rule that holds (`kgn_bench.eval.explain.category`).", "",
             "| category | failed attempts |", "|---|---:|"]
    if study.planned > study.trials:
        lines[2:2] = [f"The run is unfinished: this covers the {study.trials} of its {study.planned} trials that "
                      "have a record.", ""]
    lines += [f"| {_CATEGORY_TEXT[k]} | {v} |" for k, v in study.counts().items()]
    differ = sum(not x.same_as_recorded for x in study.explanations)
    if differ:
        lines += ["", f"{differ} re-created attempts differ from the record; their rows describe the re-creation."]
    lines += ["", "| trial | attempt | outcome | centre cm | ray cm | rotation ° | width cm | category |",
              "|---:|---:|---|---:|---:|---:|---:|---|"]
    for x in study.explanations:
        c = x.candidate
        terms = ("–",) * 4 if c is None else (f"{c.centre_cm:.2f}", f"{c.ray_cm:+.2f}", f"{c.rotation_deg:.1f}",
                                              f"{c.width_cm:+.2f}")
        lines.append(f"| {x.index} | {x.attempt} | {x.recorded.get('reason')} | {' | '.join(terms)} | "
                     f"{category(x)} |")
    lines += [f"| {f['index']} | {f['attempt']} | {f['reason']} | – | – | – | – | fault |" for f in study.faults]
    return "\n".join(lines) + "\n"


def write_failures(study: FailureStudy, out: str | Path) -> list[Path]:
    """``failures.json`` and ``failures.md`` in folder ``out``, each written atomically."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = {"run": study.run, "task": study.task, "detector": study.detector, "attempts": study.attempts,
            "trials": study.trials, "planned_trials": study.planned, "counts": study.counts(),
            "failures": [{**x.to_dict(), "category": category(x)} for x in study.explanations],
            "faults": study.faults}
    paths = [out / "failures.json", out / "failures.md"]
    atomic_write_text(paths[0], json.dumps(data, indent=2) + "\n")
    atomic_write_text(paths[1], failures_markdown(study))
    return paths

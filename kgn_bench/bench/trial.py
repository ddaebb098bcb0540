"""Benchmark trials: a work-cell scene, then capture → detect → select → execute until the protocol ends.

``single_object``: one object, one attempt. ``multi_object`` (clearance): ``objects_per_scene`` objects
spread on the table (``sim.placement.place_objects``), attempts until the table is clear,
``max_consecutive_failures`` failures in a row, a physics error, or ``max_attempts_per_object × objects``
attempts. ``pile`` and ``packed`` (VGN/GIGA's clutter rounds): the objects dropped into a box that is then
lifted away, or standing upright side by side (``pile_objects``, ``pack_objects``); the round ends by the same
rules and also as soon as no candidate passes the selector (``no_candidate`` or ``unreachable``), as in
VGN. Objects that leave the table while the scene is built are not part of the round (``fell_at_setup``);
objects pushed off it during the round are counted in ``fallen``.

Everything random in trial ``index`` is drawn from ``default_rng([seed, index])``, so a trial's outcome
depends only on the task, its seed and its index; the camera of a task with camera ranges is drawn from
``default_rng([seed, index, CAMERA_STREAM])`` (``camera_pose``), so the scene is the same whatever the
camera.

The returned record is a ``records.TrialRecord`` (its JSON form is one line of ``trials.jsonl``); its
``timing`` block (wall seconds) is the only part that varies between runs. Faults are outcomes, not crashes:
a scene that cannot be built or a MuJoCo fault becomes a ``physics_error`` attempt, and a detector whose
``reset`` or ``detect`` raises, or whose ``detect`` returns something other than ``Candidates``, a
``detector_error`` attempt.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kgn_bench.bench.scene_cache import CachedScene, load_scene, save_scene
from kgn_bench.camera import clip_far, crop_depth, orbit_pose
from kgn_bench.config import TaskConfig
from kgn_bench.detectors.base import Candidates, Detector, DetectorError, Observation
from kgn_bench.geometry import quat_wxyz_from_matrix
from kgn_bench.shapes import giga_objects, sample_shape
from kgn_bench.shapes.scaled import giga_names
from kgn_bench.sim.control import IK, Executor
from kgn_bench.sim.depth_noise import DepthNoise, DexNoise, noise_model
from kgn_bench.sim.floating_hand import FloatingHand, add_floating_cell
from kgn_bench.sim.placement import (
    GIGA_PILE,
    PileConfig,
    PlacementConfig,
    add_pile_box,
    giga_pack,
    giga_pile,
    pack_objects,
    pile_objects,
    place_objects,
    retire_outside_workspace,
    settle,
)
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.robot import PARK_Q, add_workcell, on_table
from kgn_bench.sim.scene import PhysicsError, Scene, SceneObject
from kgn_bench.sim.view_check import check_view

from .attempt import NOT_EXECUTED, AttemptResult, execute_floating, execute_grasp
from .records import AttemptRecord, TrialRecord
from .selector import ARM_WORKSPACE, GIGA_WORKSPACE, DepthView, GraspSelector, Selection

__all__ = ["ARRANGEMENTS", "CAMERA_STREAM", "TIMING_KEYS", "Capture", "camera_coordinates", "camera_pose", "capture",
           "check_cameras", "run_trial", "trial_objects"]

TIMING_KEYS = ("setup", "render", "detect", "select", "simulate")
RECORD_EVERY = 5
"""Record the state every 5 control ticks (20 Hz of simulated time)."""


CAMERA_STREAM = 7
"""Third seed word of the camera draw (``camera_pose``)."""


def camera_pose(task: TaskConfig, index: int = 0) -> np.ndarray:
    """The camera of trial ``index``, ``T_world_cam`` (OpenCV axes): the task's fixed camera, or one drawn
    from its ranges (``CameraConfig.draw``)."""
    distance, elevation, azimuth = camera_coordinates(task, index)
    T = orbit_pose(distance, np.deg2rad(elevation), np.deg2rad(azimuth))
    T[:3, 3] += np.asarray(task.camera.target)
    return T


def camera_coordinates(task: TaskConfig, index: int) -> tuple[float, float, float]:
    """``(distance m, elevation °, azimuth °)`` of trial ``index``'s camera (as ``camera_pose`` draws it)."""
    return task.camera.draw(np.random.default_rng([task.seed, index, CAMERA_STREAM]))


def check_cameras(task: TaskConfig, ik: IK | None = None) -> int:
    """Refuse a task whose cameras do not all see the workspace (``sim.view_check``): every distinct trial
    camera is checked on the empty work cell with the arm parked; ``ViewError`` names the first that fails,
    with its trial and coordinates. Returns the number of cameras checked."""
    scene = Scene([], task.camera.pinhole, extend=_workcell(task))
    _hand(task, scene, ik or IK())
    seen: set[tuple[float, float, float]] = set()
    with SceneRenderer(scene) as renderer:
        for index in range(1 if task.camera.fixed else task.n_trials):
            coords = camera_coordinates(task, index)
            if coords in seen:
                continue
            seen.add(coords)
            d, el, az = coords
            where = "the camera" if task.camera.fixed else f"the camera of trial {index}"
            check_view(renderer, scene, camera_pose(task, index), np.asarray(task.camera.target),
                       f"{task.name}: {where} (distance {d:.2f} m, elevation {el:.0f}°, azimuth {az:.0f}°)")
    return len(seen)


def trial_objects(task: TaskConfig, index: int, rng: np.random.Generator) -> list[SceneObject]:
    """The objects of trial ``index``: for a one-object protocol the set's ``index // trials``-th object;
    for GIGA's rounds their draw with replacement, at their sizes (``shapes.scaled.giga_names``,
    ``shapes.giga_objects``: a packed round's 12 candidates); for the others ``objects_per_scene`` names drawn
    without replacement while the set allows."""
    if task.spec.giga:
        arrangement = GIGA_ARRANGEMENT[task.spec.arrangement]
        shapes = giga_objects(giga_names(task.objects, arrangement, rng, task.objects_per_scene), arrangement, rng)
        return [SceneObject(shape, tuple(float(c) for c in rng.uniform(0.1, 0.9, 3))) for shape in shapes]
    if task.spec.one_object:
        names = [task.objects[index // task.trials]]
    else:
        k = task.objects_per_scene
        replace = k > len(task.objects)
        names = [task.objects[i] for i in rng.choice(len(task.objects), size=k, replace=replace)]
    return [SceneObject(sample_shape(n, rng), tuple(float(c) for c in rng.uniform(0.1, 0.9, 3)))
            for n in names]


class _Clock:
    def __init__(self) -> None:
        self.totals = dict.fromkeys(TIMING_KEYS, 0.0)

    def add(self, key: str, since: float) -> float:
        now = time.perf_counter()
        self.totals[key] += now - since
        return now


SCENE_TRIES = 5


def _spread(scene: Scene, rng: np.random.Generator) -> None:
    """Spread the objects on the table and let them settle (``sim.placement.place_objects``)."""
    place_objects(scene, rng, PlacementConfig())
    settle(scene, PlacementConfig())


def _giga_pile(scene: Scene, rng: np.random.Generator) -> None:
    """GIGA's pile (``sim.placement.giga_pile``): every object dropped is one of the round's, also one that
    then left the workspace (it fell at set-up)."""
    giga_pile(scene, rng)


def _giga_pack(scene: Scene, rng: np.random.Generator) -> list[int]:
    """GIGA's packed round (``sim.placement.giga_pack``): only the candidates that stood are the round's."""
    return giga_pack(scene, rng)


ARRANGEMENTS: dict[str, Callable[[Scene, np.random.Generator], list[int] | None]] = {
    "spread": _spread, "pile": pile_objects, "packed": pack_objects, "giga_pile": _giga_pile,
    "giga_packed": _giga_pack}
"""How a protocol puts its objects on the table (``Protocol.arrangement``), from the trial's generator; an
arrangement that tries more objects than it keeps returns the indices of the round's objects (None: all)."""

GIGA_ARRANGEMENT = {"giga_pile": "pile", "giga_packed": "packed"}
"""The GIGA arrangement (``shapes.scaled.GIGA_ARRANGEMENTS``) of each GIGA protocol's arrangement."""


Hand = Executor | FloatingHand
"""What executes a trial's grasps: the arm's executor, or the floating hand (``execution.hand``)."""


def _workcell(task: TaskConfig) -> Callable[..., None]:
    """The MJCF extension of the task's work cell: the arm and bin (or the floating hand), with the pile box if
    the protocol drops its objects into one."""
    def extend(root) -> None:
        if task.execution.hand == "floating":
            add_floating_cell(root, task.execution.geometry)
        else:
            add_workcell(root)
        if task.spec.pile_box:
            add_pile_box(root, GIGA_PILE if task.spec.giga else PileConfig())

    return extend


def _hand(task: TaskConfig, scene: Scene, ik: IK) -> Hand:
    """What executes the grasps in ``scene``, out of the camera's way: the arm parked, or the hand floating
    beyond the camera's far plane."""
    if task.execution.hand == "floating":
        hand = FloatingHand(scene, task.execution.geometry)
        hand.park()
        return hand
    executor = Executor(scene, ik)
    executor.reset(PARK_Q)
    return executor


def _ik(hand: Hand) -> IK | None:
    """The arm's IK for the selector; None for the floating hand, which reaches every pose."""
    return hand.ik if isinstance(hand, Executor) else None


def _build_scene(task: TaskConfig, index: int, ik: IK) -> tuple[Scene, Hand, list[int]]:
    """The trial's work cell with its objects placed and settled, the hand parked (retried on a blow-up), and
    the indices of the round's objects (``ARRANGEMENTS``); a first try's settled scene is kept and restored by
    later runs of the trial (``bench.scene_cache``)."""
    rng = np.random.default_rng([task.seed, index])
    arrange = ARRANGEMENTS[task.spec.arrangement]
    cached = load_scene(task, index)
    for attempt in range(SCENE_TRIES):
        scene = Scene(trial_objects(task, index, rng), task.camera.pinhole, extend=_workcell(task))
        executor = _hand(task, scene, ik)
        if cached is not None:  # this trial's set-up as an earlier run simulated it (bench.scene_cache)
            scene.restore(cached.state)
            return scene, executor, list(cached.members)
        try:
            members = arrange(scene, rng)
        except PhysicsError:
            if attempt == SCENE_TRIES - 1:
                raise
            continue
        members = list(range(len(scene.objects))) if members is None else list(members)
        if attempt == 0:  # a retried scene draws its objects after another's: only the first is kept
            save_scene(task, index, CachedScene(scene.snapshot(), tuple(members)))
        return scene, executor, members
    raise PhysicsError(f"trial {index}: no stable scene")


def _error_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}".splitlines()[0][:200]


def _trial_record(task: TaskConfig, index: int, names: list[str], placed: list[str],
                  attempts: list[AttemptRecord], removed: int, fell_at_setup: int, fallen: int,
                  clock: _Clock) -> TrialRecord:
    """The trial's record; the fallen-object counts only for a protocol that counts them (the others' records
    stay as they were)."""
    counts = task.spec.counts_fallen
    return TrialRecord(index, task.protocol, names, len(placed), placed, removed, attempts,
                       {k: round(v, 4) for k, v in clock.totals.items()},
                       fell_at_setup if counts else None, fallen if counts else None)


def _fault_record(task: TaskConfig, index: int, reason: str, detail: str, clock: _Clock,
                  names: list[str], placed: list[str]) -> TrialRecord:
    """The record of a trial that ended before its first capture (no stable scene, a detector that cannot
    reset): one failed attempt with ``reason``."""
    return _trial_record(task, index, names, placed, [AttemptRecord.failed(reason, detail)], 0,
                         len(names) - len(placed), 0, clock)


def _prepare_detector(detector: Detector, task: TaskConfig, index: int, scene: Scene) -> None:
    """The task's execution settings (``configure``), the trial's seed (``reset``) and, for a privileged
    detector, the simulator (``attach``)."""
    configure = getattr(detector, "configure", None)
    if configure is not None:
        configure(task.execution)
    detector.reset([task.seed, index])
    if detector.privileged:
        detector.attach(scene)  # type: ignore[attr-defined]


def _open_recording(record: Path | None, task: TaskConfig, index: int, scene: Scene, executor: Hand):
    if record is None:
        from kgn_bench.bench.trial_recording import NO_RECORDING

        return NO_RECORDING
    from kgn_bench.bench.trial_recording import TrialRecording

    return TrialRecording(record, f"{task.name}/trial_{index:05d}", scene.model, scene.data, executor, RECORD_EVERY)


def run_trial(task: TaskConfig, index: int, detector: Detector, ik: IK, record: Path | None = None) -> TrialRecord:
    """Run trial ``index`` of ``task`` with ``detector``; returns its record."""
    clock = _Clock()
    t = time.perf_counter()
    try:
        scene, executor, members = _build_scene(task, index, ik)
    except PhysicsError as e:
        names = [o.shape.name for o in trial_objects(task, index, np.random.default_rng([task.seed, index]))]
        clock.add("setup", t)
        return _fault_record(task, index, "physics_error", f"no stable scene: {e}", clock, names, names)
    recording = _open_recording(record, task, index, scene, executor)
    every = [o.shape.name for o in scene.objects]
    names = [every[i] for i in members]
    placed = [i for i in members if on_table(scene, i)]
    placed_names = [every[i] for i in placed]
    try:
        _prepare_detector(detector, task, index, scene)
    except Exception as e:  # a detector bug must not stop the run: record it
        recording.close()
        clock.add("setup", t)
        return _fault_record(task, index, "detector_error", f"reset: {_error_line(e)}", clock, names, placed_names)
    clock.add("setup", t)
    attempts, _ = _episode(task, index, scene, executor, detector, clock, every, recording)
    recording.close()
    removed = int(sum(a.success for a in attempts))
    left = sum(on_table(scene, i) for i in placed)
    return _trial_record(task, index, names, placed_names, attempts, removed, len(names) - len(placed),
                         max(0, len(placed) - removed - left), clock)


def _episode(task: TaskConfig, index: int, scene: Scene, executor: Hand, detector: Detector, clock: _Clock,
             names: list[str], recording, until: int | None = None) -> tuple[list[AttemptRecord], Capture | None]:
    """Capture, detect, select and execute until the protocol ends; returns the attempt records. With ``until``
    = K, stop at attempt K's selection instead, not executing it, and return it as a ``Capture`` too (None if
    the protocol ended first)."""
    cam = camera_pose(task, index)
    attempts: list[AttemptRecord] = []
    max_attempts = 1 if task.spec.one_object else task.execution.max_attempts_per_object * len(names)
    consecutive = 0
    failed: list[np.ndarray] = []  # grasps (world; executed and as chosen) that failed in this trial
    noise = noise_model(task.camera.noise_model, task.camera.depth_noise)
    with SceneRenderer(scene) as renderer:
        while len(attempts) < max_attempts and consecutive < task.execution.max_consecutive_failures:
            if not any(on_table(scene, i) for i in range(len(names))):
                break
            obs = _capture(renderer, scene, cam, noise, np.random.default_rng([task.seed, index, len(attempts)]),
                           clock, recording, task.camera.far, GIGA_WORKSPACE if task.spec.workspace_cube else None)
            if until == len(attempts) + 1:
                cands = _detect(detector, obs)
                sel = _select(task, _ik(executor), cands, obs, np.array(failed).reshape(-1, 4, 4))
                return attempts, Capture(until, scene, obs, cands, sel)
            try:
                attempt, sel, cands = _attempt(task, scene, executor, detector, obs, clock, names,
                                               np.array(failed).reshape(-1, 4, 4))
            except PhysicsError as e:  # a fault outside the grasp's own execution (the settling wait)
                attempt, sel, cands = AttemptRecord.failed("physics_error", str(e)), None, None
            attempts.append(attempt)
            if not attempt.success and sel is not None:
                failed.extend(sel.tried)
            shown = cands is not None and len(cands) > 0
            recording.attempt(len(attempts), attempt, cands.world_poses(cam) if shown else None,
                              cands.widths if shown else None, sel.scores if shown else None,
                              sel.index if shown else None)
            consecutive = 0 if attempt.success else consecutive + 1
            if attempt.reason == "physics_error":
                break
            if task.spec.ends_when_nothing_executed and attempt.reason in NOT_EXECUTED:
                break
    return attempts, None


def _observe(renderer: SceneRenderer, scene: Scene, cam: np.ndarray, noise: DepthNoise | DexNoise | None,
             rng: np.random.Generator, far: float = 0.0, crop: tuple[np.ndarray, np.ndarray] | None = None
             ) -> Observation:
    """The task camera's view ``cam`` (``T_world_cam``), its far plane ``far`` (``camera.clip_far``) and the
    depth model if any applied, then the depth cropped to the box ``crop`` (world; ``camera.crop_depth``) if
    given, as the detector's observation."""
    view = renderer.render(cam)
    depth = clip_far(view.depth, far)
    depth = depth if noise is None else noise.apply(depth, scene.intrinsics.fx, rng)
    if crop is not None:
        depth = crop_depth(depth, scene.intrinsics.K, cam, *crop)
    return Observation(view.rgb, depth, scene.intrinsics, cam)


def _capture(renderer: SceneRenderer, scene: Scene, cam: np.ndarray, noise: DepthNoise | DexNoise | None,
             rng: np.random.Generator, clock: _Clock, recording, far: float = 0.0,
             crop: tuple[np.ndarray, np.ndarray] | None = None) -> Observation:
    """``_observe``, timed and recorded."""
    t = time.perf_counter()
    obs = _observe(renderer, scene, cam, noise, rng, far, crop)
    clock.add("render", t)
    recording.observation(obs.rgb, obs.depth, scene.intrinsics.K, cam)
    return obs


def _detect(detector: Detector, obs: Observation) -> Candidates:
    """``detector.detect(obs)``, refused (``DetectorError``) when it returns something else than ``Candidates``."""
    cands = detector.detect(obs)
    if not isinstance(cands, Candidates):
        raise DetectorError(f"detect returned {type(cands).__name__}, not Candidates")
    return cands


def _select(task: TaskConfig, ik: IK | None, cands: Candidates, obs: Observation, failed: np.ndarray) -> Selection:
    """The task's selector over the candidates (world frame), on the points and depth of ``obs``."""
    points = obs.points_world(stride=task.selector.point_stride)
    workspace = GIGA_WORKSPACE if task.spec.workspace_cube else ARM_WORKSPACE
    return GraspSelector(task.selector, task.execution, ik, workspace).select(
        cands.world_poses(obs.camera_pose), cands.widths, cands.confidences, cands.reprojection_errors, points,
        failed, DepthView(obs.depth, obs.intrinsics.K, obs.camera_pose))


@dataclass
class Capture:
    """Attempt ``attempt`` of a trial up to its selection, not executed (``capture``): the ``scene`` as that
    attempt found it, the ``observation`` of the task camera, the detector's ``candidates`` (camera frame),
    the selector's ``selection`` (world frame), the records of the attempts before it (``earlier``) and the
    trial's ``hand`` (the arm's executor or the floating hand), parked, to execute the selection or another
    grasp from this state."""

    attempt: int
    scene: Scene
    observation: Observation
    candidates: Candidates
    selection: Selection
    earlier: list[AttemptRecord] = field(default_factory=list)
    hand: Hand | None = None


def capture(task: TaskConfig, index: int, detector: Detector, ik: IK, attempt: int = 1) -> Capture | None:
    """What ``run_trial`` sees and chooses at attempt ``attempt`` (1 = the first) of trial ``index``: the same
    scene, camera, depth noise, detector seed and selector, with the earlier attempts executed as in the run,
    so a deterministic detector gives the recorded selection. None when the trial ends before that attempt. A
    scene that cannot be built raises ``PhysicsError``; a detector that fails, ``DetectorError`` or its own
    exception."""
    scene, executor, _ = _build_scene(task, index, ik)
    _prepare_detector(detector, task, index, scene)
    names = [o.shape.name for o in scene.objects]
    earlier, cap = _episode(task, index, scene, executor, detector, _Clock(), names,
                            _open_recording(None, task, index, scene, executor), until=attempt)
    if cap is not None:
        cap.earlier, cap.hand = earlier, executor
    return cap


def _grasp_pose(sel: Selection | None) -> list[float] | None:
    """The executed grasp of a selection, world frame: position (m) then unit quaternion (w, x, y, z), each
    rounded to 6 decimals; None when nothing was selected."""
    if sel is None or sel.index is None or sel.grasp is None:
        return None
    T = sel.grasp
    return [round(float(v), 6) for v in (*T[:3, 3], *quat_wxyz_from_matrix(T[:3, :3]))]


def _attempt(task: TaskConfig, scene: Scene, executor: Hand, detector: Detector, obs: Observation,
             clock: _Clock, names: list[str], failed: np.ndarray
             ) -> tuple[AttemptRecord, Selection | None, Candidates | None]:
    t = time.perf_counter()
    sim0 = scene.data.time
    cands = sel = None
    try:
        cands = _detect(detector, obs)
    except Exception as e:  # a detector bug must not stop the run: record it
        clock.add("detect", t)
        result = AttemptResult("detector_error", detail=_error_line(e))
    else:
        t = clock.add("detect", t)
        sel = _select(task, _ik(executor), cands, obs, failed)
        t = clock.add("select", t)
        if sel.index is None:
            result = AttemptResult(sel.reason or "no_candidate")
        elif isinstance(executor, FloatingHand):
            result = execute_floating(executor, sel)
            if result.reason is None and result.object is not None:
                scene.retire_object(result.object)  # GIGA removes a grasped object at once
            clock.add("simulate", t)
            if task.spec.park_between_attempts and result.reason != "physics_error":
                try:
                    executor.wait(task.execution.settle_time)
                    if task.spec.workspace_cube:
                        retire_outside_workspace(scene)
                except PhysicsError as e:
                    result = AttemptResult("physics_error", detail=str(e))
        else:
            park = task.spec.park_between_attempts
            result = execute_grasp(scene, executor, sel, task.execution, park=park)
            clock.add("simulate", t)
            if park and result.reason != "physics_error":
                try:
                    executor.wait(task.execution.settle_time)
                except PhysicsError as e:
                    result = AttemptResult("physics_error", detail=str(e))
                if task.execution.remove_placed and result.reason is None and result.object is not None:
                    scene.retire_object(result.object)  # counted in the bin: out of the round's physics
    chosen = sel is not None and sel.index is not None
    record = AttemptRecord(
        success=result.reason is None,
        reason=result.reason,
        object=names[result.object] if result.object is not None else None,
        candidates=0 if cands is None else len(cands),
        selected=sel.index if chosen else None,
        score=round(float(sel.scores[sel.index]), 6) if chosen else None,
        grasp=_grasp_pose(sel),
        width=round(float(sel.width), 6) if chosen else None,
        rejected={} if sel is None else dict(sel.rejected),
        detail=result.detail,
        sim_time=round(scene.data.time - sim0, 3),
    )
    return record, sel, cands

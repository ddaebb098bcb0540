"""Typed benchmark task configs (tasks/*.toml), validated with one-line errors naming the problem.

A task file has the sections ``[task]``, ``[objects]``, ``[camera]``, ``[selector]``, ``[execution]`` and
``[resources]``;
every key is optional except ``task.name`` and ``task.protocol``. Unknown sections or keys, wrong types,
out-of-range values and unknown object names are errors (``ConfigError``).
"""

from __future__ import annotations

import re
import types
import typing
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import tomllib

from kgn_bench.camera import INTRINSICS, Intrinsics
from kgn_bench.errors import KGNBenchError
from kgn_bench.execution import GRASP_DEPTH, PREGRASP_DISTANCE
from kgn_bench.gripper import GRIPPERS, GripperGeometry
from kgn_bench.protocols import CLEARANCE_PROTOCOLS, CLUTTER_PROTOCOLS, Protocol
from kgn_bench.protocols import PROTOCOLS as PROTOCOL_TABLE
from kgn_bench.shapes import PRIMITIVES, ObjectError, is_known, known_names
from kgn_bench.shapes.library import NAME_PATTERN, packaged, set_names

__all__ = [
    "CAMERA_SPANS",
    "CLEARANCE_PROTOCOLS",
    "CLUTTER_PROTOCOLS",
    "HANDS",
    "NOISE_MODELS",
    "PROTOCOLS",
    "RAW_SELECTOR",
    "SELECTOR_MODES",
    "CameraConfig",
    "ConfigError",
    "ExecutionConfig",
    "ResourceConfig",
    "SelectorConfig",
    "TaskConfig",
    "apply_override",
    "apply_overrides",
    "load_task",
    "override_tables",
    "parse_section",
    "read_toml",
    "resolve_task",
    "task_from_dict",
]

PROTOCOLS = tuple(PROTOCOL_TABLE)
"""The protocol names (``kgn_bench.protocols.PROTOCOLS`` describes each)."""
SCORES = ("confidence_minus_error", "paper_literal")
SELECTOR_MODES = ("assisted", "raw", "top")
HANDS = ("arm", "floating")
"""What carries the gripper (``[execution] hand``): the 7-DoF arm, or nothing (a free-floating hand, GIGA's)."""
RAW_SELECTOR = {"approach_search": 0.0, "closing_search": 0.0, "centre_range": 0.0, "level_deg": 0.0,
                "min_bite": 0.0, "palm_margin": 0.0, "occlusion": False}
"""What ``selector.mode = "raw"`` switches off: the pose search, centring, levelling, the bite, the palm margin
and the occlusion check (``bench.selector``)."""


class ConfigError(KGNBenchError, ValueError):
    """A task file that cannot be used; the message names the file and the key."""


Span = float | tuple[float, float]
"""A camera coordinate: one value (fixed), or ``[lo, hi]``, drawn uniformly per trial."""


@dataclass(frozen=True)
class CameraConfig:
    """The camera: on a sphere about ``target`` (world, m) at ``distance``, ``elevation_deg`` above the table
    plane and ``azimuth_deg`` (``camera.orbit_pose``: 0 = on the +y side, 90 = on the −x side, over the
    robot). Each of the three is one value (a fixed camera, the default) or a range ``[lo, hi]`` from which
    every trial draws its own camera uniformly (``draw``; seeded by the task's seed and the trial index, on a
    stream of its own so the scene does not change with it). ``depth_noise``: strength of the depth model
    ``noise_model`` applied to every capture; 0 (the default) gives the renderer's exact depth. ``noise_model``:
    ``d435`` (the default: the D435-like stereo model of ``sim.depth_noise``, 1 = the typical D435) or ``dex``
    (GIGA's model, ``sim.depth_noise.DexNoise``, which has no strength: ``depth_noise`` 1 turns it on).
    ``intrinsics``: the pinhole camera by name (``camera.INTRINSICS``): ``realsense`` (the default, the PS
    dataset's) or ``giga`` (VGN's and GIGA's 540 px camera). ``far`` (m, 0 = off, the default): a far
    clipping plane: what lies beyond it, and where the camera sees nothing, reads ``far`` (``camera.clip_far``:
    PyBullet's camera, GIGA's at 2 m), before the depth model."""

    distance: Span = 0.8
    elevation_deg: Span = 60.0
    azimuth_deg: Span = 90.0
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    depth_noise: float = 0.0
    noise_model: str = "d435"
    intrinsics: str = "realsense"
    far: float = 0.0

    def span(self, name: str) -> tuple[float, float]:
        """``(lo, hi)`` of ``distance``, ``elevation_deg`` or ``azimuth_deg`` (lo = hi when fixed)."""
        v = getattr(self, name)
        return (float(v[0]), float(v[1])) if isinstance(v, tuple) else (float(v), float(v))

    @property
    def fixed(self) -> bool:
        return all(lo == hi for lo, hi in map(self.span, CAMERA_SPANS))

    @property
    def pinhole(self) -> Intrinsics:
        """The ``Intrinsics`` that ``intrinsics`` names (``camera.INTRINSICS``)."""
        return INTRINSICS[self.intrinsics]

    def draw(self, rng) -> tuple[float, float, float]:
        """``(distance m, elevation °, azimuth °)`` of one trial: each range drawn uniformly from ``rng`` (in
        that order), fixed values as they are."""
        out = []
        for name in CAMERA_SPANS:
            lo, hi = self.span(name)
            out.append(lo if lo == hi else float(rng.uniform(lo, hi)))
        return out[0], out[1], out[2]


CAMERA_SPANS = ("distance", "elevation_deg", "azimuth_deg")

NOISE_MODELS = ("d435", "dex")
"""The depth models ``[camera] noise_model`` can name (``sim.depth_noise.noise_model`` builds them)."""


@dataclass(frozen=True)
class SelectorConfig:
    """Grasp selection (``bench.selector``): rank by score, keep the first candidate that passes the gripper
    checks. ``score``: ``confidence_minus_error`` = c − λ·RE (the default; λ = ``reprojection_weight``,
    default 0: larger λ made no measurable difference; docs/studies/selector.md) or ``paper_literal``
    = c + RE (the paper's printed formula, kept as an ablation). A candidate closer than
    ``retry_distance`` (m) and ``retry_angle_deg`` (up to the 180° symmetry) to a grasp that already failed
    in the same trial is not tried again. ``shadow_margin`` (m): how far behind the observed surface a palm
    or wrist point must lie to count as hidden (the selector's occlusion check). ``centre_range`` (m, 0 = off):
    how far the chosen grasp may move along its closing axis to centre the observed points between the jaws
    (default 0.02; the selector study).
    ``level_deg`` (degrees, 0 = off): grasps approaching within this angle of straight down get a horizontal
    closing axis (``bench.selector.level_poses``; default 30; the selector study).
    ``palm_margin`` (m): how much the palm and wrist boxes grow in the collision check (default 0.01: the
    observed cloud is sparse and one-sided, so the bare palm grazed rims and neighbours it did not see;
    ``results/sweeps/palm_margin.md``).
    ``min_bite`` (m, 0 = off): how far up from the fingertips the enclosed observed points must reach, unless
    the table stops the fingertips first (the enclosure check; the pose search then pushes a shallow grasp
    deeper; default 0.01; ``results/sweeps/min_bite.md``).
    ``occlusion``: whether the palm and wrist must stay out of space the camera cannot see.
    ``mode``: ``assisted`` (the default: everything above) or ``raw``, detector-only execution: the
    highest-scoring candidate that passes the paper's checks (width, collision of the bare gripper with the
    observed cloud and the table, points between the fingers, IK) is executed exactly as predicted; raw
    ignores the settings in ``RAW_SELECTOR`` (``effective``). ``top``: VGN's and GIGA's evaluation, the
    detector alone: its highest-scoring candidate whose origin lies in the workspace is executed as predicted,
    with no other check and no retry memory. GIGA's hand opens fully for every grasp, so a candidate's width
    decides nothing there: a detector that finds a grasp too wide for the hand drops it itself (VGN's width mask
    does)."""

    mode: str = "assisted"
    score: str = "confidence_minus_error"
    reprojection_weight: float = 0.0
    max_candidates: int = 1000
    collision_points: int = 3
    enclosed_points: int = 5
    table_clearance: float = 0.003
    point_stride: int = 2
    shadow_margin: float = 0.01
    retry_distance: float = 0.02
    retry_angle_deg: float = 30.0
    approach_search: float = 0.03
    closing_search: float = 0.01
    search_step: float = 0.005
    centre_range: float = 0.02
    level_deg: float = 30.0
    palm_margin: float = 0.01
    min_bite: float = 0.01
    occlusion: bool = True

    def effective(self) -> SelectorConfig:
        """The settings the selector runs with: ``RAW_SELECTOR`` applied in raw mode, these otherwise."""
        return replace(self, **RAW_SELECTOR) if self.mode == "raw" else self


@dataclass(frozen=True)
class ExecutionConfig:
    """Motion parameters (m, s). ``grasp_depth``: how much further than the grasp origin the TCP goes
    along the approach (clipped so the fingertips stay ``table_clearance`` above the table).
    ``remove_placed``: in a round of several objects, an object put in the bin leaves the scene once its
    success is counted (``Scene.retire_object``), as VGN and GIGA remove a grasped object; it then makes no
    contacts, which were most of a round's physics. Off, it stays in the bin for the rest of the round (the
    protocol before 2026-12-05). No effect on ``single_object``.
    ``hand``: ``arm`` (the default: the 7-DoF arm carries the gripper, ``sim.control``) or ``floating`` (a
    gripper floating free, executed GIGA's way: ``sim.floating_hand``; the distances, timings and success rule
    are then GIGA's, ``kgn_bench.giga``, and the settings above other than ``max_consecutive_failures``,
    ``max_attempts_per_object``, ``settle_time`` and ``remove_placed`` do not apply).
    ``gripper``: the gripper by name (``gripper.GRIPPERS``): ``default`` (the benchmark's, 20 cm opening) or
    ``panda`` (the Panda hand VGN and GIGA use, 8 cm; floating only)."""

    pregrasp_distance: float = PREGRASP_DISTANCE
    grasp_depth: float = GRASP_DEPTH
    approach_time: float = 0.8
    lift_height: float = 0.15
    min_lift: float = 0.10
    max_consecutive_failures: int = 3
    max_attempts_per_object: int = 3
    settle_time: float = 0.3
    remove_placed: bool = True
    hand: str = "arm"
    gripper: str = "default"

    @property
    def geometry(self) -> GripperGeometry:
        """The ``GripperGeometry`` that ``gripper`` names (``gripper.GRIPPERS``)."""
        return GRIPPERS[self.gripper]


@dataclass(frozen=True)
class ResourceConfig:
    """What one trial (or round) reserves on a Ray cluster (``--backend ray``): ``num_cpus`` CPUs and
    ``num_gpus`` GPUs of a node (a fraction shares one: 0.25 puts four trials on a GPU). Ray schedules by these
    reservations; the trial itself still runs on one thread (``kgn_bench.threads``), so the numbers never
    change a result, only how many trials a node takes at once (raise ``num_cpus`` for scenes that need more
    memory per trial than a core's share). The local pool ignores them. Not part of a run's identity: a run
    resumes under other reservations."""

    num_cpus: float = 1.0
    num_gpus: float = 0.0

    def __post_init__(self) -> None:
        if not self.num_cpus > 0:
            raise ValueError(f"num_cpus must be > 0, got {self.num_cpus}")
        if not self.num_gpus >= 0:
            raise ValueError(f"num_gpus must be ≥ 0, got {self.num_gpus}")


@dataclass(frozen=True)
class TaskConfig:
    """A benchmark task. ``trials``: per object of ``objects`` for ``single_object``, scenes for
    ``multi_object`` (each with ``objects_per_scene`` objects drawn from ``objects``)."""

    name: str
    protocol: str
    seed: int = 0
    trials: int = 10
    objects: tuple[str, ...] = tuple(PRIMITIVES)
    objects_per_scene: int = 5
    camera: CameraConfig = field(default_factory=CameraConfig)
    selector: SelectorConfig = field(default_factory=SelectorConfig)
    execution: ExecutionConfig = field(default_factory=ExecutionConfig)
    resources: ResourceConfig = field(default_factory=ResourceConfig)

    @property
    def spec(self) -> Protocol:
        """The description of the task's protocol (``kgn_bench.protocols``)."""
        return PROTOCOL_TABLE[self.protocol]

    @property
    def clearance(self) -> bool:
        """Whether a trial is a round of attempts on several objects (``Protocol.clearance``)."""
        return self.spec.clearance

    @property
    def n_trials(self) -> int:
        """Trials of the task: ``trials`` per object of the set for a one-object protocol, else ``trials``."""
        return self.trials * len(self.objects) if self.spec.one_object else self.trials

    def with_overrides(self, trials: int | None = None, seed: int | None = None) -> TaskConfig:
        return replace(self, trials=self.trials if trials is None else trials, seed=self.seed if seed is None else seed)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _coerce(where: str, key: str, value: Any, hint: Any) -> Any:
    """Check ``value`` against the type ``hint`` of a dataclass field: ``bool``, ``int``, ``float`` (ints
    accepted), ``str``, and tuples of numbers or strings from TOML lists (``tuple[float, float]`` fixed
    length, ``tuple[int, ...]`` any length; elements typed like the hint's)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        for arm in args:
            try:
                return _coerce(where, key, value, arm)
            except ConfigError:
                continue
        raise ConfigError(f"{where}: {key} must be a number or a list of 2 numbers [lo, hi], got {value!r}")
    if origin is tuple:
        variable = len(args) == 2 and args[1] is Ellipsis
        element = args[0] if args else float
        n = None if variable else len(args)
        ok = isinstance(value, list) and (n is None or len(value) == n) and all(
            isinstance(v, str) if element is str else
            isinstance(v, int) and not isinstance(v, bool) if element is int else _is_number(v) for v in value)
        if not ok:
            kind = {int: "integers", str: "strings"}.get(element, "numbers")
            count = "a list of" if n is None else f"a list of {n}"
            raise ConfigError(f"{where}: {key} must be {count} {kind}, got {value!r}")
        return tuple(v if element is str else int(v) if element is int else float(v) for v in value)
    if hint is bool:
        ok = isinstance(value, bool)
    elif hint is float:
        ok = _is_number(value)
        value = float(value) if ok else value
    elif hint is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif hint is str:
        ok = isinstance(value, str)
    else:
        ok = True
    if not ok:
        raise ConfigError(f"{where}: {key} must be {getattr(hint, '__name__', hint)}, got {value!r}")
    return value


def parse_section(where: str, cls, table: Any, error: type[Exception] = ConfigError):
    """The dataclass ``cls`` from one TOML table: unknown keys and wrong types are ``error`` with one line
    naming ``where`` and the key; values the dataclass itself refuses (``__post_init__``) too. Every config
    of the project (tasks, plans, training) is read through this."""
    if not isinstance(table, dict):
        raise error(f"{where} must be a table")
    hints = typing.get_type_hints(cls)
    known = [f.name for f in fields(cls)]
    kwargs = {}
    try:
        for key, value in table.items():
            if key not in known:
                raise ConfigError(f"{where}: unknown key {key!r} (known: {', '.join(known)})")
            kwargs[key] = _coerce(where, key, value, hints[key])
    except ConfigError as e:
        raise error(str(e)) from None
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as e:
        if isinstance(e, KGNBenchError):
            raise error(str(e)) from None
        raise error(f"{where}: {e}") from None


def override_tables(raw: dict[str, Any], settings: list[tuple[str, str]], where: str,
                    error: type[Exception] = ConfigError) -> dict[str, Any]:
    """A copy of the parsed TOML ``raw`` with each ``(section.name, text)`` of ``settings`` set: ``text`` is read
    as a TOML value (``3``, ``1e-3``, ``true``, ``[12, 14]``, ``"frontal"``), a bare word as a string. The
    sections' own parsing then validates it (``parse_section``), so a setting of a training config is checked
    like the file's."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in raw.items()}
    for key, text in settings:
        section, _, name = key.partition(".")
        if not section or not name:
            raise error(f"{where}: setting {key!r} must be section.name")
        try:
            value = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            value = text
        table = out.setdefault(section, {})
        if not isinstance(table, dict):
            raise error(f"{where}: setting {key!r}: {section} is not a section")
        table[name] = value
    return out


def read_toml(path: Path, what: str, error: type[Exception] = ConfigError) -> dict[str, Any]:
    """The parsed TOML file ``path`` (a ``what``, named in messages); ``error`` with one line naming the file when
    it is missing, unreadable or not valid TOML."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except OSError as e:
        raise error(f"{path}: cannot read the {what} ({e.strerror})") from None
    except UnicodeDecodeError:
        raise error(f"{path}: the {what} is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: not valid TOML ({e})") from None


def resolve_task(name_or_path: str | Path) -> Path:
    """The TOML file a command line names: an existing path, else the bundled task or plan of that name
    (``single_object`` for the shipped ``tasks/single_object.toml``; a trailing ``.toml`` and a leading
    ``tasks/`` are allowed). ``ConfigError`` lists the bundled names otherwise."""
    from kgn_bench.resources import bundled_tasks

    path = Path(name_or_path)
    if path.is_file():
        return path
    bundled = bundled_tasks()
    key = path.name[:-5] if path.name.endswith(".toml") else path.name
    if path.parent in (Path("."), Path("tasks")) and key in bundled:
        return bundled[key]
    raise ConfigError(f"{name_or_path}: no such task file and no bundled task of that name "
                      f"(bundled: {', '.join(bundled)})")


def load_task(path: str | Path) -> TaskConfig:
    """Read and validate a task file, named by its path or by its bundled name (``resolve_task``)."""
    path = resolve_task(path)
    raw = read_toml(path, "task file")
    sections = {"task", "objects", "camera", "selector", "execution", "resources"}
    for name, value in raw.items():
        if name not in sections:
            raise ConfigError(f"{path}: unknown section [{name}] (known: {', '.join(sorted(sections))})")
        if not isinstance(value, dict):
            raise ConfigError(f"{path}: {name} must be a [{name}] table, got {value!r}")
    task = dict(raw.get("task", {}))
    for key in ("name", "protocol"):
        if key not in task:
            raise ConfigError(f"{path}: [task] needs {key!r}")
    allowed = {"name": "", "protocol": "", "seed": 0, "trials": 0}
    for key in task:
        if key not in allowed:
            raise ConfigError(f"{path}: [task] unknown key {key!r} (known: {', '.join(allowed)})")
        task[key] = _coerce(f"{path} [task]", key, task[key], type(allowed[key]))
    if task["protocol"] not in PROTOCOL_TABLE:
        raise ConfigError(f"{path}: protocol must be one of {', '.join(PROTOCOL_TABLE)}, got {task['protocol']!r}")
    objects = dict(raw.get("objects", {}))
    names = objects.pop("set", list(PRIMITIVES))
    per_scene = objects.pop("per_scene", 5)
    if objects:
        raise ConfigError(f"{path}: [objects] unknown key {next(iter(objects))!r} (known: set, per_scene)")
    if isinstance(names, str):
        try:
            names = set_names(names)
        except ObjectError as e:
            raise ConfigError(f"{path}: [objects] set: {e}") from None
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise ConfigError(f"{path}: [objects] set must be a non-empty list of object names, or a set's name "
                          "(pybullet_test)")
    for n in names:
        if not NAME_PATTERN.fullmatch(n):
            raise ConfigError(f"{path}: object {n!r} is not an object name (lower case, digits, _ -; no paths)")
        if not (is_known(n) or packaged(n)):
            raise ConfigError(f"{path}: unknown object {n!r} (known: {', '.join(known_names())}; "
                              "import a mesh with `kgn-bench objects add`)")
    if not isinstance(per_scene, int) or isinstance(per_scene, bool) or per_scene < 1:
        raise ConfigError(f"{path}: [objects] per_scene must be a positive integer, got {per_scene!r}")
    cfg = TaskConfig(
        name=task["name"], protocol=task["protocol"], seed=task.get("seed", 0), trials=task.get("trials", 10),
        objects=tuple(names), objects_per_scene=per_scene,
        camera=parse_section(f"{path} [camera]", CameraConfig, raw.get("camera", {})),
        selector=parse_section(f"{path} [selector]", SelectorConfig, raw.get("selector", {})),
        execution=parse_section(f"{path} [execution]", ExecutionConfig, raw.get("execution", {})),
        resources=parse_section(f"{path} [resources]", ResourceConfig, raw.get("resources", {})),
    )
    validate(cfg, str(path))
    return cfg


def task_from_dict(data: Any, where: str) -> TaskConfig:
    """The ``TaskConfig`` a run folder's ``run.json`` stores under ``config`` (``TaskConfig.to_dict``, less the
    resources, which are no part of a run's identity), checked like a task file; a key the run did not store
    takes today's default. ``ConfigError`` with one line naming ``where`` when it is not one."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: the task config must be a table")
    top = {f.name: f for f in fields(TaskConfig)}
    sections = {"camera": CameraConfig, "selector": SelectorConfig, "execution": ExecutionConfig,
                "resources": ResourceConfig}
    kwargs: dict[str, Any] = {}
    hints = typing.get_type_hints(TaskConfig)
    for key, value in data.items():
        if key not in top:
            raise ConfigError(f"{where}: unknown key {key!r} (known: {', '.join(top)})")
        if key in sections:
            kwargs[key] = parse_section(f"{where} {key}", sections[key], value)
        elif key == "objects":
            if not isinstance(value, list) or not value or not all(isinstance(n, str) for n in value):
                raise ConfigError(f"{where}: objects must be a non-empty list of object names, got {value!r}")
            kwargs[key] = tuple(value)
        else:
            kwargs[key] = _coerce(where, key, value, hints[key])
    for key in ("name", "protocol"):
        if key not in kwargs:
            raise ConfigError(f"{where}: the task config needs {key!r}")
    if kwargs["protocol"] not in PROTOCOL_TABLE:
        raise ConfigError(f"{where}: protocol must be one of {', '.join(PROTOCOL_TABLE)}, got {kwargs['protocol']!r}")
    cfg = TaskConfig(**kwargs)
    validate(cfg, where)
    return cfg


TASK_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]{0,99}")
"""A task's name: it names the run's folder under ``runs/``, so letters, digits, ``_ . -`` only, not leading
with a dot (no path separators, no absolute paths, no ``..``)."""


def validate(cfg: TaskConfig, where: str = "task") -> None:
    """Range checks shared by files and command-line overrides."""
    if not isinstance(cfg.name, str) or not TASK_NAME.fullmatch(cfg.name):
        raise ConfigError(f"{where}: task name {cfg.name!r} must be letters, digits, _ . - (not starting with a dot; "
                          "it names the run's folder)")
    bad = [n for n in cfg.objects if not NAME_PATTERN.fullmatch(n)]
    if bad:
        raise ConfigError(f"{where}: object {bad[0]!r} is not an object name (lower case, digits, _ -; no paths)")
    if cfg.trials < 1:
        raise ConfigError(f"{where}: trials must be ≥ 1, got {cfg.trials}")
    if cfg.seed < 0:
        raise ConfigError(f"{where}: seed must be ≥ 0, got {cfg.seed}")
    if cfg.selector.shadow_margin < 0:
        raise ConfigError(f"{where}: selector.shadow_margin must be ≥ 0, got {cfg.selector.shadow_margin}")
    if cfg.selector.retry_distance < 0 or not 0 <= cfg.selector.retry_angle_deg <= 180:
        raise ConfigError(f"{where}: selector.retry_distance must be ≥ 0 and retry_angle_deg in [0, 180]")
    sel = cfg.selector
    if min(sel.approach_search, sel.closing_search) < 0 or sel.search_step < 0:
        raise ConfigError(f"{where}: selector.approach_search, closing_search and search_step must be ≥ 0")
    if not 0.0 <= sel.level_deg < 90.0:
        raise ConfigError(f"{where}: selector.level_deg must be in [0, 90), got {sel.level_deg}")
    if not 0.0 <= sel.palm_margin <= 0.05:
        raise ConfigError(f"{where}: selector.palm_margin must be in [0, 0.05] m, got {sel.palm_margin}")
    if not 0.0 <= sel.min_bite <= 0.05:
        raise ConfigError(f"{where}: selector.min_bite must be in [0, 0.05] m, got {sel.min_bite}")
    if sel.centre_range < 0:
        raise ConfigError(f"{where}: selector.centre_range must be ≥ 0, got {sel.centre_range}")
    if (sel.approach_search > 0 or sel.closing_search > 0) and not 0.0005 <= sel.search_step <= 0.05:
        raise ConfigError(f"{where}: selector.search_step must be in [0.0005, 0.05] m, got {sel.search_step}")
    if cfg.selector.point_stride < 1:
        raise ConfigError(f"{where}: selector.point_stride must be ≥ 1, got {cfg.selector.point_stride}")
    if sel.mode not in SELECTOR_MODES:
        raise ConfigError(f"{where}: selector.mode must be one of {', '.join(SELECTOR_MODES)}, got {sel.mode!r}")
    if cfg.selector.score not in SCORES:
        raise ConfigError(f"{where}: selector.score must be one of {', '.join(SCORES)}, got {cfg.selector.score!r}")
    _validate_camera(cfg.camera, where)
    for name, (lo_ok, hi_ok, unit) in {"distance": (0.3, 2.0, " m"), "elevation_deg": (10.0, 90.0, ""),
                                        "azimuth_deg": (-360.0, 360.0, "")}.items():
        lo, hi = cfg.camera.span(name)
        if not (lo_ok <= lo <= hi <= hi_ok):
            raise ConfigError(f"{where}: camera.{name} must lie in [{lo_ok:g}, {hi_ok:g}]{unit} (a range as "
                              f"[lo, hi] with lo ≤ hi), got {getattr(cfg.camera, name)!r}")
    ex = cfg.execution
    if ex.max_consecutive_failures < 1:
        raise ConfigError(f"{where}: execution.max_consecutive_failures must be ≥ 1")
    if ex.hand not in HANDS:
        raise ConfigError(f"{where}: execution.hand must be one of {', '.join(HANDS)}, got {ex.hand!r}")
    if ex.gripper not in GRIPPERS:
        raise ConfigError(f"{where}: execution.gripper must be one of {', '.join(GRIPPERS)}, got {ex.gripper!r}")
    if ex.gripper != "default" and ex.hand == "arm":
        raise ConfigError(f"{where}: the arm carries the default gripper: execution.gripper = {ex.gripper!r} needs "
                          'execution.hand = "floating"')


def _validate_camera(cam: CameraConfig, where: str) -> None:
    """The camera's names and ranges (the spans are checked by the caller)."""
    if cam.noise_model not in NOISE_MODELS:
        raise ConfigError(f"{where}: camera.noise_model must be one of {', '.join(NOISE_MODELS)}, "
                          f"got {cam.noise_model!r}")
    if cam.intrinsics not in INTRINSICS:
        raise ConfigError(f"{where}: camera.intrinsics must be one of {', '.join(INTRINSICS)}, got {cam.intrinsics!r}")
    if not 0.0 <= cam.depth_noise <= 10.0:
        raise ConfigError(f"{where}: camera.depth_noise must be in [0, 10], got {cam.depth_noise}")
    if cam.far != 0.0 and not 0.3 <= cam.far <= 10.0:
        raise ConfigError(f"{where}: camera.far must be 0 (off) or in [0.3, 10] m, got {cam.far}")
    if cam.noise_model == "dex" and cam.depth_noise not in (0.0, 1.0):
        raise ConfigError(f"{where}: the dex noise model is on or off: camera.depth_noise must be 0 or 1, "
                          f"got {cam.depth_noise}")


_OVERRIDABLE = {"camera": CameraConfig, "selector": SelectorConfig, "execution": ExecutionConfig}


def apply_overrides(cfg: TaskConfig, settings: list[tuple[str, str]]) -> TaskConfig:
    """``cfg`` with every ``(key, text)`` of ``settings`` applied (``apply_override``), in order, and the result
    validated once: settings that only make sense together (``execution.hand`` and ``execution.gripper``) may
    come in any order."""
    for key, text in settings:
        cfg = apply_override(cfg, key, text, check=False)
    if settings:
        validate(cfg, "settings " + ", ".join(f"{k}={t}" for k, t in settings))
    return cfg


def apply_override(cfg: TaskConfig, key: str, text: str, check: bool = True) -> TaskConfig:
    """``cfg`` with one setting replaced: ``key`` is ``section.name`` of the camera, selector or execution
    section (e.g. ``camera.depth_noise``, ``selector.reprojection_weight``), ``text`` its value as typed on a
    command line (a number, a word, or comma-separated numbers for a vector). Validated like a task file."""
    section, _, name = key.partition(".")
    if section not in _OVERRIDABLE or not name:
        raise ConfigError(f"setting {key!r} must be section.name with section one of {', '.join(_OVERRIDABLE)}")
    current = getattr(cfg, section)
    if name not in {f.name for f in fields(current)}:
        known = ", ".join(f"{section}.{f.name}" for f in fields(current))
        raise ConfigError(f"unknown setting {key!r} (known: {known})")
    default = getattr(current, name)
    hint = typing.get_type_hints(type(current))[name]
    value: Any = text
    if isinstance(default, (bool, int, float, tuple)):
        as_list = "," in text if hint == Span else isinstance(default, tuple)
        try:
            parsed = tomllib.loads(f"v = [{text}]" if as_list else f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            raise ConfigError(f"setting {key}: cannot read {text!r} as {type(default).__name__}") from None
        value = parsed
    value = _coerce(f"setting {key}", name, value, hint)
    out = replace(cfg, **{section: replace(current, **{name: value})})
    if check:
        validate(out, f"setting {key}={text}")
    return out

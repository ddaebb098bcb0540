"""``kgn-bench replay``: a run's rerun recording opened, served, copied or drawn as a still."""

from __future__ import annotations

from pathlib import Path

from .common import writable_file
from .options import int_at_least

__all__ = ["add"]


def add(sub) -> None:
    """The ``replay`` command."""
    _add_replay(sub)


def _add_replay(sub) -> None:
    """``kgn-bench replay``: its arguments."""
    replay = sub.add_parser("replay", help="open a run's rerun recording, serve it to a browser, or save a copy")
    replay.add_argument("run", type=Path, help="run folder or .rrd file")
    replay.add_argument("--save", type=Path, help="copy the recording here instead of opening the viewer")
    replay.add_argument("--still", type=Path, metavar="PNG",
                        help="write one attempt's camera image with its candidates and executed grasp drawn on it "
                             "(no viewer needed)")
    replay.add_argument("--trial", type=int_at_least(0), default=0, help="with --still: the trial (default 0)")
    replay.add_argument("--attempt", type=int_at_least(1), default=1,
                        help="with --still: the attempt, counted from 1 (default 1)")
    replay.add_argument("--web", action="store_true",
                        help="serve the recording and rerun's web viewer on localhost (for a headless server: "
                             "open the printed URL, e.g. through SSH port forwarding); Ctrl-C stops it")
    replay.add_argument("--port", type=int_at_least(1, 65534), default=9090,
                        help="web viewer port (default 9090; the recording is served on the next port)")
    replay.set_defaults(func=_cmd_replay)


def _cmd_replay(args) -> int:
    from kgn_bench.viz.recording import RecordingError
    from kgn_bench.viz.rerun_viewer import copy_recording, open_viewer, serve_web

    path = args.run / "recording.rrd" if args.run.is_dir() else args.run
    if not path.is_file():
        raise RecordingError(f"{path} not found: run with --record first")
    for out, what in ((args.still, "still"), (args.save, "recording copy")):
        if out:
            writable_file(out, what)  # before any work, as every command checks its outputs
    with open(path, "rb") as f:
        if f.read(3) != b"RRF":  # rerun's file magic (RRF2 today)
            raise RecordingError(f"{path} is not a rerun recording (.rrd)")
    if args.still:
        from kgn_bench.viz.still import save_still

        obs = save_still(path, args.still, trial=args.trial, attempt=args.attempt)
        print(f"wrote {args.still} (trial {args.trial}, attempt {args.attempt}, {len(obs.candidates) // 4} "
              f"candidates drawn)")
        return 0
    if args.save:
        copy_recording(path, args.save)
        print(f"wrote {args.save}")
        return 0
    if args.web:
        serve_web(path, port=args.port)
        return 0
    open_viewer(path)
    return 0

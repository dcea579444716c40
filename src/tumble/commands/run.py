"""`tumble run SCENE`: simulate a scene headless, print a summary, optionally record it."""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import sys
import threading
import time

from .. import limits, signals, snapshot
from ..errors import TumbleError
from ..io.atomic import check_output
from ..progress import progress_bar
from ..runtime import init_warp, prepare_kernels
from . import add_precision_argument

HELP = "simulate a scene headless and print a summary"

DEFAULT_DURATION = 2.0

#: the SCENE argument of run, check, view and render
SCENE_HELP = "scene file (.toml), or the name of a bundled sample (e.g. sphere_pile; see samples/)"


#: frames a second of simulated time `--record` takes by default
RECORD_FPS = 60.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE", nargs="?", default=None, help=SCENE_HELP + "; left out with --resume")
    parser.add_argument(
        "--duration",
        type=float,
        default=DEFAULT_DURATION,
        metavar="S",
        help=f"simulated time in seconds (default {DEFAULT_DURATION:g}); with --resume, the time "
        "to run on from the saved moment",
    )
    parser.add_argument(
        "--save-state",
        default=None,
        metavar="FILE.npz",
        help="at the end, save the whole simulation state to FILE.npz, to continue later with "
        "--resume (written atomically, also on Ctrl-C)",
    )
    parser.add_argument(
        "--resume",
        default=None,
        metavar="FILE.npz",
        help="continue the run saved by --save-state in FILE.npz, bit for bit as if it had not "
        "stopped (the scene is stored in the file)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="N",
        help="replace the scene's [world] seed (emitters without their own seed follow it)",
    )
    parser.add_argument(
        "--record",
        default=None,
        metavar="FILE.npz",
        help="write the trajectory to FILE.npz (format in docs/scenes.md); checked before the "
        "run starts, written atomically, kept up to Ctrl-C",
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        metavar="F",
        help=f"recorded frames per second of simulated time (default {RECORD_FPS:g}, or one a step if the world "
        "takes fewer steps a second)",
    )
    parser.add_argument("--profile", action="store_true", help="print the time spent in each stage of the step")
    parser.add_argument(
        "--device", choices=("cpu", "cuda"), default="cpu", help="the Warp device to run the kernels on (default cpu)"
    )
    add_precision_argument(parser)


def _check_arguments(args: argparse.Namespace) -> None:
    if not (math.isfinite(args.duration) and args.duration > 0):
        raise TumbleError(f"--duration must be a positive number of seconds, got {args.duration:g}")
    if args.fps is not None and not (math.isfinite(args.fps) and args.fps > 0):
        raise TumbleError(f"--fps must be a positive number, got {args.fps:g}")
    if args.seed is not None and args.seed < 0:
        raise TumbleError(f"--seed must be >= 0, got {args.seed}")
    if (args.scene is None) == (args.resume is None):
        raise TumbleError("give a SCENE to run, or --resume FILE.npz to continue a saved run (not both)")
    if args.resume is not None and args.seed is not None:
        raise TumbleError("--seed cannot change a resumed run: its random state is in the saved file")
    if args.resume is not None and args.precision is not None:
        raise TumbleError("--precision cannot change a resumed run: it continues in the precision it was saved in")
    if args.record is not None:
        # before anything is simulated: a run is never lost to an unwritable output
        check_output(args.record, suffixes=(".npz",), option="--record")
    if args.save_state is not None:
        check_output(args.save_state, suffixes=(".npz",), option="--save-state")
    if args.record is not None:
        from pathlib import Path

        for option, other in (("--save-state", args.save_state), ("--resume", args.resume)):
            if other is not None and Path(args.record).resolve() == Path(other).resolve():
                # the recording would be written over the state, which is lost
                raise TumbleError(f"--record and {option} name the same file {args.record!r}; give two files")
    if args.device == "cuda":
        import warp as wp

        init_warp()
        if not wp.is_cuda_available():
            raise TumbleError("--device cuda: Warp finds no CUDA device on this machine; use --device cpu")


def main(args: argparse.Namespace) -> int:
    from ..io.record import Recorder
    from ..io.scene import load_scene, load_snapshot

    _check_arguments(args)
    if args.resume is not None:
        world = load_snapshot(args.resume, device=args.device)
        args.scene = str(world.metadata.get("path") or args.resume)
    else:
        world = load_scene(args.scene, seed=args.seed, device=args.device, precision=args.precision)
    steps = limits.check_steps("--duration", args.duration, world.dt)
    if args.fps is None:  # the default: at most one frame a step (dt = 0.05 s records 20 a second)
        args.fps = min(RECORD_FPS, 1.0 / world.dt)
    if args.record:
        _check_record_memory(args, world, steps)
    recorder = Recorder(world, fps=args.fps) if args.record else None
    try:
        _simulate(args, world, steps, recorder)
    except KeyboardInterrupt as exc:
        if recorder is None and args.save_state is None:
            raise
        # Ctrl-C or kill: keep what was recorded (written atomically; a second signal leaves no partial file)
        saved = []
        if recorder is not None:
            recorder.save(args.record)
            saved.append(f"the {recorder.frame_count:,} frames recorded so far to {args.record}")
        if args.save_state is not None:
            snapshot.save(world.snapshot(), args.save_state)
            saved.append(f"the state to {args.save_state}")
        signum = getattr(exc, "signum", signal.SIGINT)
        print(
            f"tumble run: {'interrupted' if signum == signal.SIGINT else 'terminated'} at t = {world.time:.3f} s "
            f"(step {world.step_count:,}); saved {' and '.join(saved)}",
            file=sys.stderr,
        )
        return 128 + signum
    if args.save_state is not None:
        snapshot.save(world.snapshot(), args.save_state)
        print(
            f"{'saved state':<14}  {args.save_state} (t = {world.time:.6g} s, step {world.step_count:,}; "
            f"continue with: tumble run --resume {args.save_state})"
        )
    return 0


def _check_record_memory(args: argparse.Namespace, world, steps: int) -> None:
    """Refuse a --record whose frames would not fit in memory (docs/scenes.md#limits)."""
    from ..io.record import frame_bytes

    frames = min(steps, int(args.duration * args.fps)) + 1  # at most one frame a step
    per_frame, bodies, particles = frame_bytes(world)
    try:
        limits.check_memory("--record", "frames", frames, per_frame)
    except limits.LimitError as exc:
        raise limits.LimitError(
            f"{exc} of {bodies:,} bodies and {particles:,} cloth particles; lower --fps or --duration"
        ) from None


def _simulate(args: argparse.Namespace, world, steps: int, recorder) -> None:
    """Step `world` `steps` times (recording each step), then print the summary."""
    from rich.console import Console

    err = Console(stderr=True)

    # load every kernel the world uses before the clock starts, compiling on a machine's first run
    prepare_kernels(world.device, report=lambda line: err.print(line, highlight=False))
    with interrupt_between_steps() as interrupted:
        start = time.perf_counter()
        world.step()
        if recorder is not None:
            recorder(world)
        first_step = time.perf_counter() - start
        err.print(f"first step done in {first_step:.2f} s", highlight=False)
        wall = _step_on(world, steps, recorder, err, interrupted)
    world.check_finite()  # (each step checks the state it starts from: this is what the last one left)

    if recorder is not None:
        recorder.save(args.record)
    _print_summary(args, world, steps, wall, first_step, recorder)
    if args.profile:
        _print_profile(world, steps)


class StopRequest:
    """The signal that asked the step loop to stop (`interrupt_between_steps`), if one has."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def is_set(self) -> bool:
        return self.signum is not None

    def exception(self) -> KeyboardInterrupt:
        """What the loop raises: KeyboardInterrupt for a Ctrl-C, tumble.cli's Terminated for SIGTERM or SIGHUP."""
        from ..cli import Terminated

        return KeyboardInterrupt() if self.signum in (None, signal.SIGINT) else Terminated(self.signum)


@contextlib.contextmanager
def interrupt_between_steps():
    """Turn a Ctrl-C, a SIGTERM or a SIGHUP into a request that the step loop honours between two steps.

    Yields a StopRequest that the first such signal sets; the loop then raises its exception at a clean
    point (the world between steps, the recorder holding whole frames, a state to save that a resumed
    run repeats bit for bit). A second signal raises at once, through the handlers in place before.
    Outside the main thread (signals cannot be caught there) the default behaviour is kept.
    """
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def stop(signum, frame):
        request.signum = signum
        signals.restore(previous)  # a second signal stops at once
        if signal.getsignal(signal.SIGINT) is signal.SIG_DFL:
            signal.signal(signal.SIGINT, signal.default_int_handler)

    previous = signals.replace(signals.ENDING, stop)
    try:
        yield request
    finally:
        signals.restore(previous)


def _step_on(world, steps: int, recorder, err, interrupted: StopRequest) -> float:
    """The steps after the first, with a progress bar when stderr is a terminal; returns their wall time."""
    start = time.perf_counter()
    every = max(1, (steps - 1) // 200)
    with progress_bar(
        steps - 1, "simulating", unit="steps", enabled=err.is_terminal, transient=True, console=err
    ) as advance:
        for k in range(1, steps):
            if interrupted.is_set():
                raise interrupted.exception()
            world.step()
            if recorder is not None:
                recorder(world)
            if k % every == 0:
                advance(completed=k)
    if interrupted.is_set():  # a signal during the last step
        raise interrupted.exception()
    return time.perf_counter() - start


def _print_summary(args, world, steps: int, wall: float, first_step: float, recorder) -> None:
    from ..shapes import ShapeType

    shape = world.body_shape
    counts = {s: int((shape == s).sum()) for s in ShapeType}
    rate = (steps - 1) / wall if steps > 1 and wall > 0 else 1.0 / max(first_step, 1e-9)
    # planes, spheres and boxes always; capsules, convex bodies and meshes when the world has them
    shown = [s for s in ShapeType if s <= ShapeType.BOX or counts[s]]
    lines = [
        ("scene", str(world.metadata.get("path", args.scene))),
        ("bodies", f"{world.body_count:,} ({', '.join(_count(counts[s], s.name.lower()) for s in shown)})"),
    ]
    if world.has_cloth:
        lines.append(("cloth", f"{world.cloth.particle_count:,} particles"))
    lines += [
        ("steps", f"{steps:,} ({world.time:.3f} s simulated, dt {world.dt:.6g} s, {world.substeps} substeps)"),
        ("speed", f"{rate:,.1f} steps/s ({wall:.2f} s wall after a first step of {first_step:.2f} s)"),
        ("kinetic energy", f"{world.kinetic_energy():.6g} J"),
        ("contacts", f"{world.contact_count:,}"),
        ("state hash", world.state_hash()),
    ]
    if world.emitters:
        lines.append(("emitted", _emitted(world.emitters)))
    if recorder is not None:
        lines.append(("recorded", f"{args.record} ({recorder.frame_count} frames at {recorder.fps:g} fps)"))
    width = max(len(name) for name, _ in lines)
    for name, value in lines:
        print(f"{name:<{width}}  {value}")
    sys.stdout.flush()


#: an emitter blocked this long at the end of a run is named in the summary (a busy one waits a step or two)
BLOCKED_NOTICE_S = 0.1


def _emitted(emitters) -> str:
    """'35 of 50 bodies', and which emitters have found no free spot lately ('; emitter 2 has found
    no free spot in its region for 1.2 s: is it inside a mesh or a heap?')."""
    text = f"{sum(e.emitted for e in emitters):,} of {sum(e.count for e in emitters):,} bodies"
    blocked = [(k, e) for k, e in enumerate(emitters, 1) if not e.done and e.blocked_for >= BLOCKED_NOTICE_S]
    for k, e in blocked:
        text += (
            f"; emitter {k} has found no free spot in its region for the last {e.blocked_for:.3g} s"
            " (is its region inside a mesh, or under a heap?)"
        )
    return text


def _count(n: int, noun: str) -> str:
    """'1 box', '3 boxes', '1,000 spheres', '2 meshes'."""
    return f"{n:,} {noun}" if n == 1 else f"{n:,} {noun}{'es' if noun.endswith(('x', 'sh')) else 's'}"


def _print_profile(world, steps: int) -> None:
    total = sum(world.profile.values())
    print()
    print(f"{'stage':<14}{'seconds':>10}{'%':>8}{'ms/step':>10}")
    for stage, seconds in sorted(world.profile.items(), key=lambda item: -item[1]):
        share = 100.0 * seconds / total if total > 0 else 0.0
        print(f"{stage:<14}{seconds:>10.3f}{share:>8.1f}{1000.0 * seconds / steps:>10.3f}")
    print(f"{'total':<14}{total:>10.3f}{100.0:>8.1f}{1000.0 * total / steps:>10.3f}")

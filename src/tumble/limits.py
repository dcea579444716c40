"""Limits on what a scene or a command may ask for, checked before anything is allocated.

Two kinds (the table in docs/scenes.md, "Limits", lists them all):

- **Solver limits**, fixed numbers: the largest `dt`, `substeps`, bodies released per step and
  steps per run. Beyond them a request does not fail, it hangs or silently goes wrong
  (`substeps = 1e9` never finishes a step; `dt = 1e9` drops a ball through the ground).
- **Memory limits**, derived from the machine: a request's estimated bytes (bodies, cloth
  particles, recorded frames, GIF frames; `BYTES_PER_*` below, measured) against the memory
  available now (`available_memory()`), so that a request too big to hold is refused with one
  line instead of dying halfway in an allocation.

Every refusal is a `LimitError` (a `ValueError`) whose message names the key, the request and
the limit, e.g. "count: 1,000,000,000 bodies need about 2.0 TB; 21.6 GB is available (at most
11,000,000 bodies)".
"""

from __future__ import annotations

import math
import os
import re

from .errors import TumbleError

#: largest time step [s]: a body falling under 9.81 m/s^2 moves g dt^2 = 10 cm in one step of
#: 0.1 s, more than the thickness of the thin shapes contacts are tested against
MAX_DT = 0.1
#: smallest time step [s]: a step of 5e-324 s made 1 / h overflow (ZeroDivisionError in the solver's
#: parameters) and a float32 cloth's rates non-finite; a nanosecond is far below any step a scene needs
MIN_DT = 1e-9
#: largest number of solver substeps per step (the cost of a step is linear in it)
MAX_SUBSTEPS = 1000
#: most cloth substeps in one step: springs too stiff for the step need dt / stable substep of them
#: (springs.stable_substep), and stiffness 1e300 asked for 1e150, a step that never ended
MAX_CLOTH_SUBSTEPS = 10_000
#: largest number of steps in one run (duration / dt): about 12 days at 1 ms a step
MAX_STEPS = 10**9
#: largest seed of a random generator (the world's, an emitter's, the wind's): seeds are kept as int64
#: (recordings, snapshots); NumPy would take any integer, and one of 400 digits passed `tumble check`
MAX_SEED = 2**63 - 1
#: most bodies one emitter releases in one step (rate * dt): each new body is tested against the
#: ones placed before it in the same step, so the cost grows as its square (1,000: ~1.5 s, 2,000: ~6 s,
#: 10,000: ~100 s measured on one loaded core)
MAX_RELEASE_PER_STEP = 1_000
#: widest and tallest image in pixels, for the viewer and for headless export
MAX_IMAGE_SIDE = 8192
#: most frames one `tumble render` writes (an hour of video at 30 fps is 108,000)
MAX_FRAMES = 1_000_000
#: largest scene file [bytes]: a scene is a page of text; meshes go in their own files (a device
#: such as /dev/zero, or a log given by mistake, would otherwise be read until memory ran out)
MAX_SCENE_BYTES = 64_000_000
#: particle, spring and triangle indices are int32: at most this many cloth particles (~6 springs each)
MAX_PARTICLES_INT32 = (2**31 - 1) // 8

#: memory a world needs per body [bytes]: 600-800 measured (state, broad phase, contacts, sphere
#: grid at rest), doubled for the arrays' growth by doubling
BYTES_PER_BODY = 2048
#: memory per cloth particle [bytes]: 3,000-3,900 measured (64 x 64 and 400 x 400), doubled
BYTES_PER_PARTICLE = 8192
#: memory of one local wedge worker process [bytes]: 220 MB measured (Python, NumPy, Warp, Dask and a
#: small scene), doubled for larger scenes and the final frame's rendering
BYTES_PER_WORKER = 512 * 2**20
#: recording memory per body per frame [bytes]: 13 float64 held per frame plus the padded copy saved
BYTES_PER_BODY_FRAME = 256
#: recording memory per cloth particle per frame [bytes]: its state (position, velocity, pin target), held and copied
BYTES_PER_PARTICLE_FRAME = 192

#: environment variable capping the memory Tumble plans with, e.g. "2G" (default: what the machine has)
MEMORY_ENV = "TUMBLE_MEMORY"


class LimitError(TumbleError, ValueError):
    """A request beyond one of Tumble's limits; the message names the key, the request and the limit."""


def parse_bytes(text: str) -> int:
    """Bytes from "2G", "512M", "1.5 GB", "100000" (binary multiples: K = 1024)."""
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)i?b?\s*", str(text), re.IGNORECASE)
    if not match:
        raise LimitError(f"{MEMORY_ENV}={text!r}: expected a size such as 2G, 512M or 100000")
    scale = 1024 ** ("kmgt".find(match.group(2).lower()) + 1) if match.group(2) else 1
    return int(float(match.group(1)) * scale)


def available_memory() -> int:
    """Bytes this process can still allocate: the least of the machine's available memory, the
    cgroup's remaining allowance, the address-space limit left, and $TUMBLE_MEMORY when set."""
    candidates = []
    if os.environ.get(MEMORY_ENV):
        candidates.append(parse_bytes(os.environ[MEMORY_ENV]))
    try:
        with open("/proc/meminfo") as f:
            info = dict(line.split(":", 1) for line in f if ":" in line)
        candidates.append(int(info["MemAvailable"].split()[0]) * 1024)
    except (OSError, KeyError, ValueError):
        try:
            candidates.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            cap = f.read().strip()
        if cap != "max":
            with open("/sys/fs/cgroup/memory.current") as f:
                candidates.append(max(0, int(cap) - int(f.read().strip())))
    except (OSError, ValueError):
        pass
    try:
        import resource

        soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/statm") as f:
                used = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            candidates.append(max(0, soft - used))
    except (ImportError, OSError, ValueError):
        pass
    return min(candidates) if candidates else 2**40


def show_bytes(n: float) -> str:
    """'512 B', '3.2 MB', '1.9 TB' (decimal units, as `df -H` shows them)."""
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} PB"  # unreachable


def check_memory(key: str, what: str, count: float, bytes_each: float, *, available: int | None = None) -> None:
    """Refuse `count` items of `bytes_each` when they do not fit in the available memory.

    Args:
        key: what the user wrote that asks for them, e.g. "count" or "--record".
        what: the items, plural, e.g. "bodies".
    """
    need = float(count) * float(bytes_each)
    have = available_memory() if available is None else available
    if need > have:
        most = int(have // bytes_each)
        raise LimitError(
            f"{key}: {_show_count(count)} {what} need about {show_bytes(need)} of memory; "
            f"{show_bytes(have)} is available (at most {most:,} {what})"
        )


def check_steps(key: str, duration: float, dt: float) -> int:
    """The number of steps of `duration` at `dt`, refused beyond `MAX_STEPS`."""
    steps = duration / dt
    if not math.isfinite(steps) or steps > MAX_STEPS:
        raise LimitError(
            f"{key}: {duration:g} s at dt {dt:g} s is {_show_count(steps)} steps; the limit is {MAX_STEPS:,} steps"
        )
    return max(1, int(round(steps)))


def _show_count(n: float) -> str:
    return f"{int(n):,}" if math.isfinite(n) and n < 1e15 else f"{n:.3g}"

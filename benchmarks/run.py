"""Run the benchmark scenes in Tumble, PyBullet, MuJoCo and Rapier, side by side, on one CPU core.

    PYTHONPATH=src python benchmarks/run.py                         # everything (~13-15 min)
    PYTHONPATH=src python benchmarks/run.py --scenes pile_1k,cloth_64
    PYTHONPATH=src python benchmarks/run.py --scenes pile --engines tumble
    PYTHONPATH=src python benchmarks/run.py --quick                 # 0.5 s per scene
    PYTHONPATH=src python benchmarks/run.py --device cuda           # Tumble on the GPU
    PYTHONPATH=src python benchmarks/run.py --quality               # every engine at its settings for quality

For each scene the engines are built once and then stepped in alternating chunks (0.1 s of
simulated time each), so that a change in machine load touches every engine alike. Warm-up
(Tumble's kernel compilation included) happens on a small copy of the scene and is not timed.
Figures, quality checks and the CSV columns are explained in benchmarks/README.md.

The first comparison runs every engine at its defaults. `--quality` is the second: every engine
at the settings its documentation recommends for accuracy (each adapter's docstring in
engines.py says which and where from), compared by simulated seconds per wall-clock second
beside the quality columns.
"""

from __future__ import annotations

import os

# one thread everywhere, set before NumPy / MuJoCo / Warp load their thread pools
for _var in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import datetime  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from importlib import metadata  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
# run as a script: make `benchmarks` and the checkout's `tumble` importable
sys.path.insert(0, str(HERE.parent))
if (HERE.parent / "src" / "tumble").is_dir():
    sys.path.insert(0, str(HERE.parent / "src"))

from benchmarks import joints as joint_bench  # noqa: E402
from benchmarks import meshes as mesh_bench  # noqa: E402
from benchmarks import quality  # noqa: E402
from benchmarks.engines import ADAPTERS  # noqa: E402
from benchmarks.scenes import (  # noqa: E402
    BOX3D_LARGE_PYRAMID_MS,
    LARGE_PYRAMID_TOP_TOLERANCE,
    SCENES,
    SPHERE_MASS,
    SPHERE_RADIUS,
    Scene,
    cloth_edges,
)

GROUPS = {
    "all": list(SCENES),
    "pile": ["pile_1k", "pile_5k", "pile_20k"],
    "cloth": ["cloth_64", "cloth_128"],
}
QUICK_DURATION = 0.5  # [s] simulated per scene with --quick


def other_precision() -> str:
    """The engine that runs Tumble in the precision other than its default, for the row beside the default's."""
    from tumble.precision import DEFAULT_PRECISION

    return "tumble_f32" if DEFAULT_PRECISION == "float64" else "tumble_f64"


CHUNK_DURATION = 0.1  # [s] simulated per turn when alternating engines
MAX_WALL = 180.0  # [s] of stepping per engine and scene before it stops early

# targets of issue 7 (one CPU core, ratios measured in the same run)
TARGET_PILE_RATIO = 10.0  # pile_5k body-steps/s vs PyBullet
TARGET_CLOTH_RATIO = 10.0  # cloth_64 steps/s vs PyBullet
TARGET_CLOTH_STRAIN = 0.10
TARGET_PILE_100K = 10.0  # steps/s

# targets of issue 19 (one core, Tumble's steps/s over Rapier's in the same run, at both defaults)
TARGET_RAPIER = {"box_pyramid": 1.0, "pile_1k": 1.5, "pile_5k": 4.0, "boxes_1k": 1.5}
TARGET_PILE_100K_19 = 5.0  # steps/s
TARGET_CLOTH_128 = 100.0  # steps/s, with strain <= TARGET_CLOTH_STRAIN


@dataclass
class Result:
    """Timing and quality of one engine on one scene over `steps` steps."""

    scene: Scene
    engine: str
    steps: int = 0
    seconds: float = 0.0
    quality: dict = field(default_factory=dict)
    error: str = ""
    note: str = ""
    settings: str = ""  # the engine's solver settings (time step, iterations, substeps)
    profile: dict = field(default_factory=dict)  # Tumble's World.profile: stage -> seconds
    max_strain: float = math.nan  # cloth: largest strain seen so far
    early: bool = False  # Tumble's figures over the peers' shorter interval
    checkpoints: list = field(default_factory=lambda: [(0, 0.0)])  # (steps, seconds) after each turn

    def seconds_at(self, steps: int) -> float:
        """Wall-clock seconds this engine took for its first `steps` steps (interpolated)."""
        done, spent = zip(*self.checkpoints)
        return float(np.interp(steps, done, spent))

    @property
    def sim_time(self) -> float:
        return self.steps * self.scene.dt

    @property
    def steps_per_s(self) -> float:
        return self.steps / self.seconds if self.seconds > 0 else math.nan

    @property
    def body_steps_per_s(self) -> float:
        return self.steps_per_s * self.scene.body_count

    @property
    def realtime(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time / self.seconds if self.seconds > 0 else math.nan


# ---------------------------------------------------------------------- machine


def machine_description(device: str) -> dict[str, str]:
    """CPU model, core count, GPU (for cuda), package versions and the date."""
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass

    def version(package: str) -> str:
        try:
            return metadata.version(package)
        except metadata.PackageNotFoundError:
            return "not installed"

    tumble_version = "unknown"
    try:
        import tumble

        tumble_version = tumble.__version__
    except Exception:  # noqa: BLE001 - a broken checkout still gets a machine line
        pass
    try:  # the checkout's commit, when run from a git checkout
        import subprocess

        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=HERE, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        if commit:
            tumble_version += f" (git {commit})"
    except (OSError, subprocess.SubprocessError):
        pass
    gpu = ""
    if device.startswith("cuda"):
        import warp as wp

        wp.config.quiet = True
        wp.init()
        gpu = wp.get_device(device).name
    return {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": cpu,
        "cores": str(os.cpu_count()),
        "load": f"{os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else "",
        "gpu": gpu,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "warp": version("warp-lang"),
        "pybullet": version("pybullet"),
        "mujoco": version("mujoco"),
        "rapier": version("rapier3d"),
        "tumble": tumble_version,
    }


def machine_name(info: dict[str, str]) -> str:
    """A file-name slug for the machine: CPU model and core count (and GPU)."""
    text = f"{info['cpu']} {info['cores']}c" + (f" {info['gpu']}" if info["gpu"] else "")
    text = re.sub(r"\((R|TM)\)|CPU|Processor|@.*?GHz", " ", text, flags=re.IGNORECASE)
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def pin_to_one_core(cpu: int | None) -> int | None:
    """Restrict this process to one CPU core (default: the last allowed one); returns it."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    core = allowed[-1] if cpu is None else cpu
    os.sched_setaffinity(0, {core})
    return core


# ---------------------------------------------------------------------- measuring


def measure_quality(adapter, scene: Scene) -> dict[str, float]:
    """Quality figures of the adapter's current state (see quality.py); NaN if not finite."""
    nan = {
        "overlap": math.nan,
        "ground": math.nan,
        "wall": math.nan,
        "kinetic_energy": math.nan,
        "strain": math.nan,
        "top": math.nan,
    }
    if scene.kind == "cloth":
        x = adapter.cloth_position()
        if not np.isfinite(x).all():
            return nan
        n = scene.count
        return {**nan, "strain": quality.cloth_max_strain(x, cloth_edges(n), 1.0 / (n - 1))}
    s = adapter.bodies()
    if not all(np.isfinite(a).all() for a in s.values()):
        return nan
    planes = adapter.init.planes
    if scene.kind == "pile":
        overlap = quality.sphere_max_overlap(s["position"], SPHERE_RADIUS)
        depth = quality.plane_penetration(s["position"], planes, radius=SPHERE_RADIUS)
        inertia = 0.4 * SPHERE_MASS * SPHERE_RADIUS**2  # solid sphere: 2/5 m r^2
        mass = SPHERE_MASS
    else:
        half = adapter.init.half_extents
        q = s["orientation"] / np.linalg.norm(s["orientation"], axis=1, keepdims=True)
        overlap = quality.box_max_overlap(s["position"], q, half)
        depth = quality.plane_penetration(s["position"], planes, orientation=q, half_extents=half)
        mass = adapter.init.mass
        inertia = mass * (2 * half[0]) ** 2 / 6.0  # cube: m a^2 / 6
    # pyramids: how far the top body (the highest at the start) has moved from its start
    top = math.nan
    if scene.kind in ("pyramid", "large_pyramid"):
        start = adapter.init.position
        i = int(np.argmax(start[:, 2]))
        top = float(np.linalg.norm(s["position"][i] - start[i]))
    return {
        "overlap": overlap,
        "ground": float(depth[0]),
        "wall": float(np.max(depth[1:])) if len(depth) > 1 else math.nan,
        "kinetic_energy": quality.kinetic_energy(s["velocity"], s["angular_velocity"], mass, inertia),
        "strain": math.nan,
        "top": top,
    }


def warm_up(engine: str, scene: Scene, device: str, quality: bool = False) -> None:
    """Build and step a small copy of the scene, so compilation and first-use costs are not timed."""
    small = {"pile": 64, "boxes": 27, "pyramid": 6, "large_pyramid": 10, "cloth": 8}[scene.kind]
    tiny = Scene(f"{scene.name}_warmup", scene.kind, small, box_width=1.0, dt=scene.dt)
    adapter = ADAPTERS[engine](tiny, device, quality=quality)
    adapter.step(3)
    adapter.sync()
    measure_quality(adapter, tiny)
    adapter.close()


def run_scene(
    scene: Scene,
    engines: list[str],
    device: str,
    chunk: int,
    max_wall: float,
    log,
    all_peers: bool = False,
    quality: bool = False,
) -> list[Result]:
    """Run one scene in every engine, alternating chunks; returns the results (see `Result`).

    An engine stops early, with the simulated time it reached, once it has spent `max_wall`
    seconds stepping. `quality`: every engine at its settings for accuracy (engines.py).
    """
    adapters, results, targets = {}, {}, {}
    for engine in engines:
        if not engine.startswith("tumble") and not scene.peers:
            continue
        reason = dict(scene.skip).get(engine)
        if reason and not all_peers:
            log(f"  {engine}: left out: {reason} (--all-peers runs it)")
            continue
        result = results[engine] = Result(scene, engine)
        targets[engine] = scene.steps if engine.startswith("tumble") else scene.peer_steps
        try:
            warm_up(engine, scene, device, quality)
            start = time.perf_counter()
            adapters[engine] = ADAPTERS[engine](scene, device, quality=quality)
            result.settings = adapters[engine].settings()
            log(f"  {engine}: built in {time.perf_counter() - start:.1f} s")
        except Exception as error:  # noqa: BLE001 - one engine failing must not stop the others
            result.error = f"{type(error).__name__}: {error}"
            log(f"  {engine}: could not build: {result.error}")
    # Tumble's figures at the step where a peer stopped, so that quality compares equal times
    early: dict[int, Result] = {}
    early_peers: dict[int, list[str]] = {}

    def running(engine: str) -> bool:
        r = results[engine]
        return engine in adapters and r.steps < targets[engine] and not r.error and r.seconds < max_wall

    # alternate: every engine advances one chunk per round until it has done its steps
    while True:
        active = [e for e in adapters if running(e)]
        if not active:
            break
        for engine in active:
            adapter, result = adapters[engine], results[engine]
            k = min(chunk, targets[engine] - result.steps)
            if engine == "tumble":
                # do not step past a peer's last step: Tumble's state there is compared with the peer's
                ends = [targets[e] for e in adapters if e != "tumble" and targets[e] > result.steps]
                k = min([k, *(t - result.steps for t in ends)])
            try:
                start = time.perf_counter()
                adapter.step(k)
                adapter.sync()
                result.seconds += time.perf_counter() - start
                result.steps += k
                result.checkpoints.append((result.steps, result.seconds))
            except Exception as error:  # noqa: BLE001
                result.error = f"{type(error).__name__} at step {result.steps}: {error}"
                log(f"  {engine}: {result.error}")
                continue
            if scene.kind == "cloth":
                # the largest strain over the run, sampled after every turn (not timed)
                strain = measure_quality(adapter, scene)["strain"]
                result.max_strain = strain if math.isnan(result.max_strain) else max(result.max_strain, strain)
        log(
            "  t = "
            + ", ".join(f"{e} {results[e].sim_time:.2f} s ({results[e].steps_per_s:.1f} steps/s)" for e in adapters)
        )
        # a peer that stopped this round stopped where Tumble is now: take Tumble's figures there
        tumble = results.get("tumble")
        if tumble is not None and running("tumble"):
            for engine in active:
                peer = results[engine]
                if engine != "tumble" and not running(engine) and peer.steps == tumble.steps and not peer.error:
                    row = early.setdefault(tumble.steps, Result(scene, "tumble", early=True))
                    row.steps, row.seconds, row.checkpoints = tumble.steps, tumble.seconds, list(tumble.checkpoints)
                    early_peers.setdefault(tumble.steps, []).append(engine)
                    row.note = f"first {row.sim_time:g} s, as {' and '.join(early_peers[tumble.steps])}"
                    row.quality = measure_quality(adapters["tumble"], scene)
                    row.quality["strain"] = tumble.max_strain

    for engine, adapter in adapters.items():
        if results[engine].steps < targets[engine] and not results[engine].error:
            results[engine].note = f"stopped at the {max_wall:g} s cap"
        if not results[engine].error:
            results[engine].quality = measure_quality(adapter, scene)
            if scene.kind == "cloth":
                results[engine].quality["strain"] = results[engine].max_strain
        if engine == "tumble" and hasattr(adapter, "world") and adapter.world is not None:
            results[engine].profile = dict(adapter.world.profile)
        adapter.close()
    out = list(results.values())
    return out[:1] + [early[k] for k in sorted(early)] + out[1:] if "tumble" in results else out


def tumble_ratio(results: list[Result], peer: Result) -> float:
    """Tumble's steps per second divided by the peer's, over the steps both have done."""
    tumble = next((r for r in results if r.engine == "tumble" and not r.error and r.steps), None)
    if tumble is None or peer.error or not peer.steps:
        return math.nan
    steps = min(tumble.steps, peer.steps)
    return peer.seconds_at(steps) / tumble.seconds_at(steps)


# ---------------------------------------------------------------------- reporting


def fmt(value: float, scale: float = 1.0, digits: int = 2) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value * scale:.{digits}f}"


def rate(value: float) -> str:
    if not math.isfinite(value):
        return "-"
    return f"{value:,.0f}" if value >= 100 else f"{value:.1f}"


def _console():
    from rich.console import Console

    # wide enough for the table when the output goes to a file or pipe
    return Console() if sys.stdout.isatty() else Console(width=200)


def print_table(all_results: list[Result], info: dict[str, str], device: str) -> None:
    from rich.table import Table

    title = (
        f"Tumble vs PyBullet, MuJoCo and Rapier, Tumble on {device}, {info['cpu']} ({info['cores']} cores, "
        f"one used), {info['date']}"
    )
    table = Table(title=title, title_justify="left")
    for name, justify in [
        ("scene", "left"),
        ("engine", "left"),
        ("settings", "left"),
        ("sim s", "right"),
        ("steps/s", "right"),
        ("body-steps/s", "right"),
        ("sim s/wall s", "right"),
        ("Tumble ×", "right"),
        ("overlap mm", "right"),
        ("ground mm", "right"),
        ("wall mm", "right"),
        ("KE J", "right"),
        ("strain %", "right"),
    ]:
        table.add_column(name, justify=justify)
    previous = None
    for r in all_results:
        scene_results = [x for x in all_results if x.scene.name == r.scene.name and not x.early]
        if previous is not None and previous != r.scene.name:
            table.add_section()
        previous = r.scene.name
        engine = r.engine + (f" ({r.note})" if r.note else "")
        if r.error:
            table.add_row(r.scene.name, engine, r.settings, fmt(r.sim_time), "[red]failed[/red]", *[""] * 8)
            continue
        q = r.quality
        ratio = "" if r.engine == "tumble" else fmt(tumble_ratio(scene_results, r), digits=1)
        table.add_row(
            r.scene.name,
            engine,
            r.settings,
            f"{r.sim_time:.2f}",
            rate(r.steps_per_s),
            rate(r.body_steps_per_s),
            fmt(r.realtime),
            ratio,
            fmt(q.get("overlap"), 1e3),
            fmt(q.get("ground"), 1e3),
            fmt(q.get("wall"), 1e3),
            fmt(q.get("kinetic_energy"), digits=3),
            fmt(q.get("strain"), 100, 1),
        )
    console = _console()
    console.print(table)
    console.print(
        "Tumble × = Tumble's steps/s divided by the peer's, both over the steps both did. Rows 'first ... s' give "
        "Tumble's figures where a peer stopped (its planned interval or the wall-time cap). "
        "Quality figures are taken at the end of each row's interval; cloth strain is the largest "
        "over the interval, sampled every 0.1 s."
    )
    for r in all_results:
        if r.error:
            console.print(f"[red]{r.scene.name} / {r.engine} failed:[/red] {r.error}", markup=True, highlight=False)


def check_targets(all_results: list[Result]) -> list[tuple[str, str, bool | None]]:
    """The targets of issues 7 and 19 as (target, measured, passed); passed is None if not measured."""

    def find(scene: str, engine: str, steps: int | None = None) -> Result | None:
        for r in all_results:
            if r.scene.name == scene and r.engine == engine and not r.error and r.steps:
                if (steps is None and not r.early) or r.steps == steps:
                    return r
        return None

    def scene_results(scene: str) -> list[Result]:
        return [r for r in all_results if r.scene.name == scene and not r.early]

    def ratio_check(scene: str, target: str, least: float) -> tuple[str, str, bool | None]:
        """Tumble's speed against PyBullet's on `scene`, at least `least` times."""
        pb = find(scene, "pybullet")
        if not (pb and find(scene, "tumble")):
            return (target, "not measured", None)
        ratio = tumble_ratio(scene_results(scene), pb)
        return (target, f"{ratio:.1f}x", ratio >= least)

    checks = [ratio_check("pile_5k", "pile 5k: >= 10x PyBullet body-steps/s", TARGET_PILE_RATIO)]
    pb = find("pile_5k", "pybullet")
    tb = find("pile_5k", "tumble", pb.steps) if pb else None
    if pb and tb:
        checks.append(
            (
                f"pile 5k: overlap and ground penetration <= PyBullet's (at {pb.sim_time:g} s)",
                f"overlap {tb.quality['overlap'] * 1e3:.2f} vs {pb.quality['overlap'] * 1e3:.2f} mm, "
                f"ground {tb.quality['ground'] * 1e3:.2f} vs {pb.quality['ground'] * 1e3:.2f} mm",
                tb.quality["overlap"] <= pb.quality["overlap"] and tb.quality["ground"] <= pb.quality["ground"],
            )
        )
    else:
        checks.append(("pile 5k: overlap and ground penetration <= PyBullet's", "not measured", None))
    checks.append(ratio_check("cloth_64", "cloth 64x64: >= 10x PyBullet steps/s", TARGET_CLOTH_RATIO))
    tb = find("cloth_64", "tumble")
    checks.append(
        (
            "cloth 64x64: largest strain <= 10 %",
            f"{tb.quality['strain'] * 100:.1f} % (over {tb.sim_time:g} s)" if tb else "not measured",
            None if tb is None else tb.quality["strain"] <= TARGET_CLOTH_STRAIN,
        )
    )
    tb = find("pile_100k", "tumble")
    checks.append(
        (
            "pile 100k: >= 10 steps/s (issue 7)",
            f"{tb.steps_per_s:.1f} steps/s (over {tb.sim_time:g} s)" if tb else "not measured",
            None if tb is None else tb.steps_per_s >= TARGET_PILE_100K,
        )
    )
    # issue 19: against Rapier, with overlap and ground penetration no worse than Rapier's
    for scene, least in TARGET_RAPIER.items():
        ra, tb = find(scene, "rapier"), find(scene, "tumble")
        if not (ra and tb):
            checks.append((f"{scene}: >= {least:g}x Rapier steps/s (issue 19)", "not measured", None))
            continue
        ratio = tumble_ratio(scene_results(scene), ra)
        checks.append((f"{scene}: >= {least:g}x Rapier steps/s (issue 19)", f"{ratio:.2f}x", ratio >= least))
    checks.append(
        (
            f"pile 100k: >= {TARGET_PILE_100K_19:g} steps/s (issue 19)",
            f"{tb.steps_per_s:.1f} steps/s" if (tb := find("pile_100k", "tumble")) else "not measured",
            None if tb is None else tb.steps_per_s >= TARGET_PILE_100K_19,
        )
    )
    tb = find("cloth_128", "tumble")
    checks.append(
        (
            f"cloth 128x128: >= {TARGET_CLOTH_128:g} steps/s with strain <= 10 % (issue 19)",
            f"{tb.steps_per_s:.1f} steps/s, {tb.quality['strain'] * 100:.1f} %" if tb else "not measured",
            None if tb is None else tb.steps_per_s >= TARGET_CLOTH_128 and tb.quality["strain"] <= TARGET_CLOTH_STRAIN,
        )
    )
    tb = find("large_pyramid", "tumble")
    measured = "not measured"
    passed = None
    if tb:
        measured = (
            f"top cube moved {tb.quality['top'] * 1e3:.1f} mm in {tb.sim_time:g} s; "
            f"{1e3 / tb.steps_per_s:.1f} ms/step ({tb.settings}) against Box3D's {BOX3D_LARGE_PYRAMID_MS:.2f} ms/step "
            "(dt 1/60, 4 substeps, one thread of an AMD 7950X)"
        )
        if tb.sim_time >= tb.scene.duration - 0.5 * tb.scene.dt:  # a shortened run cannot tell
            passed = tb.quality["top"] <= LARGE_PYRAMID_TOP_TOLERANCE
    checks.append(
        (
            f"Box3D's large pyramid stands: top cube within {LARGE_PYRAMID_TOP_TOLERANCE * 1e3:g} mm after 10 s",
            measured,
            passed,
        )
    )
    return checks


def markdown_report(all_results: list[Result], info: dict[str, str], device: str, quality: bool = False) -> str:
    """The results table and the targets as Markdown, for docs/performance.md."""
    lines = [
        f"Measured {info['date']} with `benchmarks/run.py{'' if device == 'cpu' else ' --device ' + device}`: "
        f"{info['cpu']}, {info['cores']} cores, one used"
        + (", every engine at its settings for quality (`--quality`)" if quality else "")
        + (f", GPU {info['gpu']}" if info["gpu"] else "")
        + f"; load average {info['load']} at the end; Python {info['python']}, NumPy {info['numpy']}, "
        f"Warp {info['warp']}, PyBullet {info['pybullet']}, MuJoCo {info['mujoco']}, "
        f"Rapier {info['rapier']}, Tumble {info['tumble']}.",
        "",
        "| scene | engine | settings | sim s | steps/s | body-steps/s | sim s/wall s | Tumble × | overlap mm "
        "| ground mm | wall mm | KE J | strain % |",
        "|---|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for r in all_results:
        scene_results = [x for x in all_results if x.scene.name == r.scene.name and not x.early]
        engine = r.engine + (f" ({r.note})" if r.note else "")
        if r.error:
            lines.append(
                f"| {r.scene.name} | {engine} | {r.settings} | {fmt(r.sim_time)} | failed: {r.error[:80]} "
                "| | | | | | | | |"
            )
            continue
        q = r.quality
        ratio = "" if r.engine == "tumble" else fmt(tumble_ratio(scene_results, r), digits=1)
        lines.append(
            f"| {r.scene.name} | {engine} | {r.settings} | {r.sim_time:.2f} | {rate(r.steps_per_s)} | {rate(r.body_steps_per_s)} "
            f"| {fmt(r.realtime)} | {ratio} | {fmt(q.get('overlap'), 1e3)} | {fmt(q.get('ground'), 1e3)} | {fmt(q.get('wall'), 1e3)} "
            f"| {fmt(q.get('kinetic_energy'), digits=3)} | {fmt(q.get('strain'), 100, 1)} |"
        )
    if quality:  # the targets are set at the engines' defaults
        return "\n".join(lines) + "\n"
    lines += ["", "| target | measured | result |", "|---|---|---|"]
    for target, measured, passed in check_targets(all_results):
        lines.append(
            f"| {target} | {measured} | {'not measured' if passed is None else ('pass' if passed else 'FAIL')} |"
        )
    return "\n".join(lines) + "\n"


def update_doc(path: Path, report: str, device: str, quality: bool = False) -> None:
    """Replace the block between this device's markers in `path` (append it if missing); the
    `--quality` comparison has a block of its own."""
    device = ("cuda" if device.startswith("cuda") else device) + (" quality" if quality else "")
    begin, end = f"<!-- results {device}: written by benchmarks/run.py --doc -->", f"<!-- end of results {device} -->"
    text = path.read_text() if path.exists() else ""
    block = f"{begin}\n{report}{end}"
    if begin in text and end in text:
        text = text[: text.index(begin)] + block + text[text.index(end) + len(end) :]
    else:
        text = text.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(text)


CSV_FIELDS = [
    "date",
    "device",
    "scene",
    "engine",
    "settings",
    "early",
    "note",
    "bodies",
    "sim_time_s",
    "steps",
    "wall_s",
    "steps_per_s",
    "body_steps_per_s",
    "tumble_ratio",
    "max_overlap_m",
    "max_ground_penetration_m",
    "max_wall_penetration_m",
    "kinetic_energy_J",
    "max_strain",
    "top_displacement_m",
    "error",
    "cpu",
    "cores",
    "load",
    "gpu",
    "python",
    "numpy",
    "warp",
    "pybullet",
    "mujoco",
    "rapier",
    "tumble",
]


def write_csv(path: Path, all_results: list[Result], info: dict[str, str], device: str) -> None:
    """Write the results, keeping the file's rows of other (device, scene, engine) triples."""
    rows = []
    for r in all_results:
        scene_results = [x for x in all_results if x.scene.name == r.scene.name and not x.early]
        q = r.quality
        rows.append(
            {
                **info,
                "device": device,
                "scene": r.scene.name,
                "engine": r.engine,
                "settings": r.settings,
                "note": r.note,
                "early": "yes" if r.early else "",
                "bodies": r.scene.body_count,
                "sim_time_s": f"{r.sim_time:.4f}",
                "steps": r.steps,
                "wall_s": f"{r.seconds:.3f}",
                "steps_per_s": f"{r.steps_per_s:.4g}",
                "body_steps_per_s": f"{r.body_steps_per_s:.4g}",
                "tumble_ratio": "" if r.engine == "tumble" else f"{tumble_ratio(scene_results, r):.4g}",
                "max_overlap_m": f"{q.get('overlap', math.nan):.4g}",
                "max_ground_penetration_m": f"{q.get('ground', math.nan):.4g}",
                "max_wall_penetration_m": f"{q.get('wall', math.nan):.4g}",
                "kinetic_energy_J": f"{q.get('kinetic_energy', math.nan):.4g}",
                "max_strain": f"{q.get('strain', math.nan):.4g}",
                "top_displacement_m": f"{q.get('top', math.nan):.4g}",
                "error": r.error,
            }
        )
    key = ("device", "scene", "engine")
    fresh = {tuple(row[k] for k in key) for row in rows}
    kept = []
    if path.exists():
        with path.open(newline="") as f:
            kept = [row for row in csv.DictReader(f) if tuple(row.get(k, "") for k in key) not in fresh]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(kept + rows)


def print_profile(all_results: list[Result]) -> None:
    """Tumble's time per stage (ms per step), from `World.profile`."""
    from rich.table import Table

    rows = [r for r in all_results if r.engine == "tumble" and not r.early and r.profile]
    if not rows:
        return
    stages = sorted({s for r in rows for s in r.profile}, key=lambda s: -max(r.profile.get(s, 0) for r in rows))
    table = Table(title="Tumble: milliseconds per step in each stage (World.profile)", title_justify="left")
    table.add_column("scene")
    for s in stages:
        table.add_column(s, justify="right")
    for r in rows:
        table.add_row(r.scene.name, *[f"{1e3 * r.profile.get(s, 0.0) / max(r.steps, 1):.2f}" for s in stages])
    _console().print(table)


# ---------------------------------------------------------------------- command line


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--scenes",
        default="all",
        help=f"comma-separated scene names or groups (all, pile, cloth); scenes: {', '.join(SCENES)}",
    )
    parser.add_argument(
        "--engines",
        default=f"tumble,{other_precision()},pybullet,mujoco,rapier",
        help="comma-separated engines (tumble_f32, tumble_f64: Tumble in that precision, beside the default's row)",
    )
    parser.add_argument("--device", default="cpu", help="Warp device for Tumble: cpu (default) or cuda")
    parser.add_argument("--quick", action="store_true", help=f"simulate at most {QUICK_DURATION} s per scene")
    parser.add_argument("--duration", type=float, default=None, help="simulate at most this many seconds per scene")
    parser.add_argument(
        "--max-wall",
        type=float,
        default=MAX_WALL,
        help=f"stop an engine on a scene after this many seconds of stepping (default {MAX_WALL:g})",
    )
    parser.add_argument(
        "--all-peers",
        action="store_true",
        help="also run the peers a scene leaves out by default (PyBullet on cloth_128)",
    )
    parser.add_argument(
        "--quality",
        action="store_true",
        help="the second comparison: every engine at the settings its docs recommend for accuracy",
    )
    parser.add_argument("--machine", default=None, help="name of the CSV file (default: from the CPU model)")
    parser.add_argument("--output", type=Path, default=HERE / "results", help="folder for the CSV")
    parser.add_argument("--no-csv", action="store_true", help="do not write the CSV")
    parser.add_argument(
        "--doc",
        type=Path,
        default=None,
        help="also write the table and targets as Markdown into this file (docs/performance.md), "
        "replacing the block of the same device",
    )
    parser.add_argument("--cpu", type=int, default=None, help="CPU core to run on (default: the last one)")
    parser.add_argument("--no-pin", action="store_true", help="do not restrict the process to one core")
    args = parser.parse_args(argv)
    names = []
    args.joint_list = []  # joint scenes (benchmarks/joints.py): not in "all", run with --scenes joints
    args.mesh_pour = False  # the mesh row (benchmarks/meshes.py, Tumble only): --scenes meshes
    for item in filter(None, (s.strip() for s in args.scenes.split(","))):
        if item in ("meshes", "mesh_pour_5k"):
            args.mesh_pour = True
        elif item == "joints" or item in joint_bench.SCENES:
            args.joint_list += list(joint_bench.SCENES) if item == "joints" else [item]
        elif item in GROUPS:
            names += GROUPS[item]
        elif item in SCENES:
            names.append(item)
        else:
            parser.error(f"unknown scene {item!r}; choose from {', '.join([*GROUPS, *SCENES])}")
    args.scene_list = list(dict.fromkeys(names))
    args.engine_list = [e.strip() for e in args.engines.split(",") if e.strip()]
    for engine in args.engine_list:
        if engine not in ADAPTERS:
            parser.error(f"unknown engine {engine!r}; choose from {', '.join(ADAPTERS)}")
    if args.quick:
        args.duration = min(args.duration or QUICK_DURATION, QUICK_DURATION)
    if args.duration is not None and not (args.duration > 0):
        parser.error("--duration must be > 0")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        import warp as wp

        wp.config.quiet = True  # no banner in the middle of the log
    except ImportError:
        pass
    core = None if args.no_pin else pin_to_one_core(args.cpu)
    info = machine_description(args.device)
    print(
        f"{info['cpu']}, {info['cores']} cores (running on core {core}), load {info['load']}, "
        f"python {info['python']}, warp {info['warp']}, pybullet {info['pybullet']}, mujoco {info['mujoco']}, "
        f"rapier {info['rapier']}"
    )

    all_results: list[Result] = []
    for name in args.scene_list:
        scene = SCENES[name] if args.duration is None else SCENES[name].shortened(args.duration)
        print(
            f"{scene.name}: {scene.body_count:,} bodies, {scene.duration:g} s"
            + (f" (peers {scene.peer_duration:g} s)" if scene.peers and scene.peer_duration != scene.duration else ""),
            flush=True,
        )
        chunk = max(1, int(round(CHUNK_DURATION / scene.dt)))
        all_results += run_scene(
            scene,
            args.engine_list,
            args.device,
            chunk,
            args.max_wall,
            lambda s: print(s, flush=True),
            all_peers=args.all_peers,
            quality=args.quality,
        )

    joint_rows = []
    for name in dict.fromkeys(args.joint_list):
        print(f"{name} (benchmarks/joints.py): {args.duration or joint_bench.DURATION:g} s", flush=True)
        for engine in args.engine_list:
            joint_rows.append(joint_bench.run(name, engine, args.duration or joint_bench.DURATION))
    if joint_rows and not args.no_csv:
        path = args.output / f"joints-{args.machine or machine_name(info)}.csv"
        joint_bench.write_csv(path, joint_rows)
        print(f"wrote {path}")
    if args.mesh_pour:
        print(
            f"mesh_pour_5k (benchmarks/meshes.py): {args.duration or mesh_bench.DURATION:g} s, Tumble only", flush=True
        )
        row = mesh_bench.run(args.duration or mesh_bench.DURATION, args.device)
        if not args.no_csv:
            path = args.output / f"meshes-{args.machine or machine_name(info)}.csv"
            joint_bench.write_csv(path, [row])
            print(f"wrote {path}")
    if not args.scene_list:
        return 0

    info["load"] = f"{os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else ""
    print()
    print_table(all_results, info, args.device)
    print_profile(all_results)
    console = _console()
    for target, measured, passed in [] if args.quality else check_targets(all_results):
        mark = (
            "[yellow]not measured[/yellow]"
            if passed is None
            else ("[green]pass[/green]" if passed else "[red]FAIL[/red]")
        )
        console.print(f"target: {target}: {measured} -> {mark}")
    if args.doc is not None:
        report = markdown_report(all_results, info, args.device, args.quality)
        update_doc(args.doc, report, args.device, args.quality)
        print(f"updated {args.doc}")
    if not args.no_csv:
        # shortened runs go to a file of their own, so they never replace the full figures
        suffix = ("" if args.duration is None else f"-{args.duration:g}s") + ("-quality" if args.quality else "")
        path = args.output / f"{args.machine or machine_name(info)}{suffix}.csv"
        write_csv(path, all_results, info, args.device)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

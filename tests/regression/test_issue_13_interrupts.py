"""Ctrl-C at any moment of a command: one line on stderr, exit 130, never a traceback.

Issue 13 (bad input, huge requests and failed writes), found by a reliability probe: a Ctrl-C in
the first second or two of `tumble ...`, while Python imported Tumble and Warp and before
`tumble.cli.main` could catch it, printed a KeyboardInterrupt traceback of 20 to 40 lines
(`timeout -s INT 1 tumble run rain` showed it every time).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest


def _ctrl_c_as_in_a_terminal() -> None:
    """In the child before it starts: SIGINT at its default, as a terminal's foreground command has it
    (a test run started in the background of a shell has SIGINT ignored, and its children with it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _with_warp_interrupted(tmp_path: Path, env: dict) -> dict:
    """`env` in which `import warp` raises KeyboardInterrupt, as a Ctrl-C during the import does."""
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "warp.py").write_text("raise KeyboardInterrupt\n")
    return dict(env, PYTHONPATH=os.pathsep.join([str(fake), env["PYTHONPATH"]]))


@pytest.mark.parametrize("how", ["python -m tumble", "console script"])
def test_ctrl_c_while_tumble_imports_is_one_line(tmp_path, tumble_subprocess_env, how):
    """Interrupted in `import tumble` (Warp's import): "tumble: interrupted", status 130 (SIGINT)."""
    env = _with_warp_interrupted(tmp_path, tumble_subprocess_env)
    if how == "console script":  # what pip writes for [project.scripts] tumble = "tumble.cli:main"
        script = tmp_path / "bin" / "tumble"
        script.parent.mkdir()
        script.write_text("import sys\nfrom tumble.cli import main\nsys.exit(main())\n")
        command = [sys.executable, str(script)]
    else:
        command = [sys.executable, "-m", "tumble"]
    result = subprocess.run([*command, "run", "bouncing_ball"], capture_output=True, text=True, env=env, timeout=120)
    assert result.stderr == "tumble: interrupted\n"
    assert result.returncode in (130, -signal.SIGINT)  # Python ends an unhandled Ctrl-C by SIGINT


def test_sigterm_while_tumble_imports_is_one_line_and_status_143(tmp_path, tumble_subprocess_env):
    """`kill` in `import tumble` (Warp's import), before `tumble.cli.main` handles it: "tumble: terminated",
    status 143, where Python's default ended the process silently, killed by the signal."""
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "warp.py").write_text("import os, signal, time\nos.kill(os.getpid(), signal.SIGTERM)\ntime.sleep(60)\n")
    env = dict(tumble_subprocess_env, PYTHONPATH=os.pathsep.join([str(fake), tumble_subprocess_env["PYTHONPATH"]]))
    result = subprocess.run(
        [sys.executable, "-m", "tumble", "run", "bouncing_ball"], capture_output=True, text=True, env=env, timeout=120
    )
    assert (result.returncode, result.stderr) == (143, "tumble: terminated\n")


def test_a_program_importing_tumble_keeps_its_traceback(tmp_path, tumble_subprocess_env):
    """Only the command is quiet: a program that imports Tumble sees Python's own KeyboardInterrupt."""
    env = _with_warp_interrupted(tmp_path, tumble_subprocess_env)
    result = subprocess.run(
        [sys.executable, "-c", "import tumble"], capture_output=True, text=True, env=env, timeout=120
    )
    assert "Traceback" in result.stderr and result.stderr.rstrip().endswith("KeyboardInterrupt")


@pytest.mark.parametrize("delay", [0.3, 1.0])
def test_an_early_ctrl_c_is_one_line(tmp_path, tumble_subprocess_env, delay):
    """A real SIGINT soon after the start (in the imports, or just after): one line, no traceback."""
    out = tmp_path / "ball.npz"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tumble", "run", "rain", "--duration", "60", "--record", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=tumble_subprocess_env,
        preexec_fn=_ctrl_c_as_in_a_terminal,
    )
    try:
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("first step")]
    assert len(lines) == 1 and "interrupted" in lines[0], err
    assert proc.returncode in (130, -signal.SIGINT)
    assert [p.name for p in tmp_path.iterdir() if p.name != "ball.npz"] == []


# ------------------------------------------------------------------------------------------------ wedges

BALLS = """
[world]
seed = 1

[[plane]]
normal = [0, 0, 1]

[[emitter]]
rate = 400
count = 12
position = [0, 0, 0.8]
region = "box"
extent = [0.3, 0.3, 0.1]
radius = 0.04
mass = 0.1
"""


def test_ctrl_c_of_a_running_wedge_is_one_line(tmp_path, tumble_subprocess_env):
    """A terminal's Ctrl-C reaches every process of the command: each local worker printed a
    KeyboardInterrupt traceback (and Dask logged a CancelledError one as it closed); now the wedge
    says "interrupted" in one line, exit 130, and leaves no temporary file."""
    scene = tmp_path / "balls.toml"
    scene.write_text(BALLS, encoding="utf-8")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tumble", "wedge", str(scene), "--vary", "world.seed=0..5", "-o", str(out)]
        + ["--duration", "100", "--workers", "1", "--keep", "record"],  # a variant: seconds, not 0.2 s
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=tumble_subprocess_env,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=_ctrl_c_as_in_a_terminal,
    )
    try:
        deadline = time.monotonic() + 180
        seen = ""
        while "wedge:" not in seen and time.monotonic() < deadline and proc.poll() is None:
            seen += proc.stderr.readline()  # "wedge: 6 variants, on 1 worker ..." once the cluster is up
        time.sleep(3)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    err = seen + err
    assert "Traceback" not in err and "Exception" not in err, err
    assert err.strip().splitlines()[-1] == "tumble wedge: interrupted", err
    assert proc.returncode == 130
    assert [p for p in out.rglob(".*")] == []


def test_a_wedge_removes_what_a_lost_worker_was_writing(tmp_path):
    """A worker stopped in the middle of a write (the cluster closed on a Ctrl-C, a worker killed for
    memory) left `.video.mp4.XXXXXXXX.tmp.mp4` in its variant's folder: the next wedge over it removes
    such temporary files, and only those."""
    import tumble

    scene = tmp_path / "balls.toml"
    scene.write_text(BALLS, encoding="utf-8")
    out = tmp_path / "out"
    folder = out / "world.seed=1"
    folder.mkdir(parents=True)
    partial = [".video.mp4.ehr6ts7g.tmp.mp4", ".record.npz.a1b2c3d_.tmp.npz", ".scene.usdc.k2j3h4g5.tmp.usdc"]
    mine = [".scene.toml.swp", ".notes", "notes.tmp.mp4"]
    for name in partial + mine:
        (folder / name).write_bytes(b"half")
    table = tumble.wedge(scene, {"world.seed": "1"}, out=out, duration=0.05, workers=1, progress=False)
    assert [row["status"] for row in table] == ["ok"]
    assert sorted(p.name for p in folder.iterdir() if p.name.startswith(".") or "tmp" in p.name) == sorted(mine)

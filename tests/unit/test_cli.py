"""The `tumble` command line (tumble.cli): one-line errors and exit status 2 on bad scene files, in a
subprocess, for every command that reads one; the parser's record of its commands and options. (Each
command's own behaviour is tested in tests/unit/commands/test_<command>.py.)"""

from __future__ import annotations

import subprocess
import sys

import pytest

from tumble.cli import COMMANDS, build_parser

BAD_FILES = {
    "unknown key": ("[[sphere]]\nposition = [0, 0, 1]\nradius = 0.1\ncolour = 'red'\n", "colour"),
    "negative radius": ("[[sphere]]\nposition = [0, 0, 1]\nradius = -1\n", "radius"),
    "zero normal": ("[[plane]]\nnormal = [0, 0, 0]\n", "normal"),
    "nan": ("[[box]]\nposition = [0, 0, nan]\nhalf_extents = [1, 1, 1]\n", "position"),
    "malformed toml": ("[[sphere]\nposition = [0, 0, 1]\n", "line 1"),
}


@pytest.mark.parametrize(
    "command, case",
    [("check", case) for case in BAD_FILES] + [("run", "unknown key"), ("run", "malformed toml")],
    ids=[f"check-{case}" for case in BAD_FILES] + ["run-unknown key", "run-malformed toml"],
)
def test_bad_file_exits_2_with_one_line(write_scene, tumble_subprocess_env, command, case):
    """Exit with status 2 and one line on stderr naming file and key, without a traceback."""
    text, fragment = BAD_FILES[case]
    path = write_scene(text, "bad.toml")
    result = subprocess.run(
        [sys.executable, "-m", "tumble", command, str(path)],
        capture_output=True,
        text=True,
        env=tumble_subprocess_env,
        timeout=120,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert lines[0].startswith(f"tumble {command}: error: ")
    assert "bad.toml" in lines[0] and fragment in lines[0]
    assert result.stdout == ""


def test_the_parser_lists_its_commands_and_every_option():
    """build_parser() keeps one parser per command in `commands`, each with every argument it takes in `options`."""
    parser = build_parser()
    assert list(parser.commands) == list(COMMANDS)
    flags = {name: [f for a in p.options for f in a.option_strings] for name, p in parser.commands.items()}
    for name, listed in flags.items():
        assert listed[:2] == ["-h", "--help"] and "--debug" in listed, name
        assert len(listed) == len(set(listed)), name
    assert {"--duration", "--record", "--fps", "--resume"} <= set(flags["run"])
    # the arguments of a mutually exclusive group are listed as the parser's own
    assert {"--duration", "--frames"} <= set(flags["export"])
    # and what is listed is what the parser takes: each option's value lands under its dest
    export = {a.dest: a for a in parser.commands["export"].options}
    args = parser.parse_args(["export", "sphere_pile", "-o", "x.usda", "--frames", "12"])
    assert args.frames == 12 and export["frames"].type is int and args.output == "x.usda"
    # the positional SCENE argument is an option too, with no flags
    assert [a.dest for a in parser.commands["check"].options if not a.option_strings] == ["scene"]


def test_a_sighup_ignored_as_under_nohup_stays_ignored(tumble_subprocess_env):
    """Started with SIGHUP ignored (`nohup tumble ...`), the command keeps ignoring it."""
    import signal
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "tumble", "run", "sphere_pile", "--duration", "600"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=tumble_subprocess_env,
        preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN),
    )
    assert proc.stderr is not None
    for line in proc.stderr:  # stepping
        if line.startswith("first step done"):
            break
    proc.send_signal(signal.SIGHUP)
    time.sleep(1.0)
    running = proc.poll() is None
    proc.terminate()
    proc.communicate(timeout=60)
    assert running and proc.returncode == 143


def test_an_interruption_that_c_code_swallowed_is_raised_again_but_not_inside_its_own_cleanup(tumble_subprocess_env):
    """C code that looks an attribute up (NumPy on an enum member) may clear the exception a signal
    handler raised, and a render sent `kill` ran on to its end: the handlers raise it again every
    INTERRUPT_RETRY_S until it is seen unwinding, and leave a `finally` that is cleaning up alone."""
    script = """
import os, signal, sys, time
from tumble import cli
interrupts = cli._Interrupts()
interrupts.install()
try:
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)
    except BaseException:
        pass  # swallowed, as C code does
    start = time.monotonic()
    while time.monotonic() - start < 10 * cli.INTERRUPT_RETRY_S:
        pass
    print("ran on")
except cli.Terminated:
    waited = time.monotonic() - start
    print("raised again", waited <= 2 * cli.INTERRUPT_RETRY_S)
try:
    try:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
    finally:
        start = time.monotonic()
        while time.monotonic() - start < 3 * cli.INTERRUPT_RETRY_S:
            pass
        print("cleaned up")
except KeyboardInterrupt as exc:
    print("one", type(exc).__name__)
interrupts.restore()
"""
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, env=tumble_subprocess_env
    )
    assert result.stdout.split("\n")[:3] == ["raised again True", "cleaned up", "one KeyboardInterrupt"], (
        result.stdout + result.stderr
    )


@pytest.mark.parametrize("number", ["SIGTERM", "SIGHUP"])
def test_sigterm_unwinds_as_ctrl_c_and_leaves_no_temporary_file(tmp_path, tumble_subprocess_env, number):
    """`kill` (SIGTERM) during a render: exit 143 with one line, the user's earlier file unchanged and
    no temporary output left beside it (the render's atomic write is unwound, as on Ctrl-C). SIGHUP
    (the terminal closed) too, with status 129: it ended the render at once, leaving its temporary file."""
    import signal
    import time

    out = tmp_path / "movie.mp4"
    out.write_bytes(b"the user's earlier file")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "tumble",
            "render",
            "bouncing_ball",
            "-o",
            str(out),
            "--duration",
            "600",
            "--size",
            "64x48",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=tumble_subprocess_env,
    )
    deadline = time.monotonic() + 120
    while not any(p.name != out.name for p in tmp_path.iterdir()):  # the render's temporary output
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read() if proc.stderr else ""
        time.sleep(0.2)
    proc.send_signal(getattr(signal, number))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + getattr(signal, number), err
    assert err.strip().splitlines()[-1] == "tumble render: terminated" and "Traceback" not in err
    assert out.read_bytes() == b"the user's earlier file"
    assert [p.name for p in tmp_path.iterdir()] == [out.name]

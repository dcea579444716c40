"""Bad input to `tumble wedge`: one line each, exit status 2, before anything runs or is written."""

from __future__ import annotations

import socket

import pytest

from tumble.cli import main as cli_main
from tumble.wedge import MAX_VARIANTS


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--vary", "emitter[0].rat=1,2"], "did you mean 'emitter[0].rate'"),
        (["--vary", "plane[0].frcition=0.1"], "did you mean 'plane[0].friction'"),
        (["--vary", "world.substeps=2,2.5"], "[world] substeps: must be an integer, got 2.5"),
        (["--vary", "plane[0].friction=true"], "friction: must be a number, got true"),
        (["--vary", "world.seed=9..3"], "empty range"),
        (["--vary", "emitter[0].rate=100:900:0"], "empty range"),
        (["--vary", f"world.seed=0..{MAX_VARIANTS}"], f"more than the limit of {MAX_VARIANTS:,}"),
        (["--vary", "world.seed=0..1", "--keep", "video,usb"], "unknown --keep 'usb'"),
        (["--vary", "world.seed=0..1", "--address", "not an address"], "should be a scheduler address"),
        (["--vary", "world.seed=0..1", "--duration", "-1"], "duration must be a positive number"),
    ],
)
def test_bad_input_one_line_before_running(args, message, tmp_path, capsys):
    """Exit 2 with one line naming the problem, and write nothing."""
    out = tmp_path / "out"
    assert cli_main(["wedge", "sphere_pile", "-o", str(out), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err
    assert len(err.splitlines()) == 1
    assert not out.exists()


def test_unreachable_address_fails_fast(tmp_path, capsys):
    """Give up on a scheduler that does not answer within --connect-timeout, with one line."""
    out = tmp_path / "out"
    address = f"tcp://127.0.0.1:{_free_port()}"
    code = cli_main(
        [
            "wedge",
            "sphere_pile",
            "-o",
            str(out),
            "--vary",
            "world.seed=0..1",
            "--address",
            address,
            "--connect-timeout",
            "1",
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert f"--address {address}: no Dask scheduler answered within 1 s" in err
    assert len(err.splitlines()) == 1
    assert not out.exists()

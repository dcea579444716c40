"""`tumble plot` (tumble.commands.plot) from the command line, in process: a recording to an image, its
checks before reading, its one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

import tumble
import tumble.cli
from tumble.io.scene import SAMPLES_DIR


@pytest.fixture
def cli(monkeypatch):
    """tumble.cli.main with only the plot command (the others' imports are not needed)."""
    monkeypatch.setattr(tumble.cli, "COMMANDS", {"plot": "plot"})
    return tumble.cli.main


def _recording(path):
    t = np.linspace(0.0, 1.0, 11)
    np.savez(
        path,
        time=t,
        position=np.zeros((11, 1, 3)),
        velocity=np.zeros((11, 1, 3)),
        mass=np.ones(1),
        gravity=np.array([0, 0, -9.81]),
        contact_count=np.zeros(11),
    )
    return path


def test_plot_command_writes_png(tmp_path, cli):
    """tumble plot RECORD.npz -o OUT.png writes a PNG."""
    _recording(tmp_path / "r.npz")
    rc = cli(["plot", str(tmp_path / "r.npz"), "-o", str(tmp_path / "p.png")])
    assert rc == 0
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_command_missing_file_exits_2(tmp_path, cli, capsys):
    """A missing recording: exit status 2 and the path in the message."""
    rc = cli(["plot", str(tmp_path / "nope.npz"), "-o", str(tmp_path / "p.png")])
    assert rc == 2
    assert "nope.npz" in capsys.readouterr().err


def test_run_record_then_plot(tmp_path, monkeypatch):
    """A recording from tumble run --record plots with every body panel filled in."""
    from tumble.io.plot import build_figure
    from tumble.io.record import load_recording

    monkeypatch.setattr(tumble.cli, "COMMANDS", {"run": "run", "plot": "plot"})
    record = tmp_path / "ball.npz"
    assert (
        tumble.cli.main(
            [
                "run",
                str(SAMPLES_DIR / "bouncing_ball.toml"),
                "--duration",
                "0.25",
                "--record",
                str(record),
                "--fps",
                "20",
            ]
        )
        == 0
    )
    assert tumble.cli.main(["plot", str(record), "-o", str(tmp_path / "ball.png")]) == 0
    fig = build_figure(load_recording(record))
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    assert titles == ["Kinetic energy", "Potential energy", "Linear momentum", "Contact count"]


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["-o", "p.txt"], "-o"),  # the output's suffix is checked before the recording is read
        (["--dpi", "5", "-o", "p.png"], "--dpi must be between 10 and 2000, got 5"),
        ([], "-o OUT is required"),
    ],
)
def test_bad_output_or_dpi_exits_2_with_one_line(tmp_path, cli, capsys, monkeypatch, argv, fragment):
    """A wrong -o suffix, a --dpi out of range, or no -o for a recording: exit 2, one line, nothing written."""
    monkeypatch.chdir(tmp_path)
    record = _recording(tmp_path / "r.npz")
    assert cli(["plot", str(record), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tumble plot: error:") and fragment in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]


def test_dpi_sets_the_image_size(tmp_path, cli):
    """--dpi 50 gives a PNG half as wide and high as the default 100 dpi."""
    import struct

    record = _recording(tmp_path / "r.npz")
    sizes = []
    for dpi in ("100", "50"):
        out = tmp_path / f"p{dpi}.png"
        assert cli(["plot", str(record), "-o", str(out), "--dpi", dpi]) == 0
        sizes.append(struct.unpack(">II", out.read_bytes()[16:24]))
    assert sizes[1] == (sizes[0][0] // 2, sizes[0][1] // 2)

"""io/atomic.py: outputs checked before any work; files and frame folders replaced whole or not at all."""

from __future__ import annotations

import os
import stat

import pytest

from tumble.io.atomic import AtomicFile, OutputError, atomic_folder, atomic_path, check_folder, check_output


def test_check_output_accepts_a_writable_target_and_leaves_nothing(tmp_path):
    """A good path comes back as a Path; the probe file it made is gone."""
    assert check_output(str(tmp_path / "run.npz"), suffixes=(".npz",)) == tmp_path / "run.npz"
    assert check_output(tmp_path / "RUN.NPZ", suffixes=(".npz",)).name == "RUN.NPZ"  # suffixes ignore case
    assert check_output(tmp_path / "frames", folder=True) == tmp_path / "frames"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("make", "kwargs", "message"),
    [
        (lambda p: p / "run.txt", {"suffixes": (".npz", ".mp4")}, "must end in .npz or .mp4"),
        (lambda p: p / "missing" / "run.npz", {}, "no such directory"),
        (lambda p: p, {}, "is a directory, not a file"),
        (lambda p: (p / "file").write_text("x") and p / "file" / "run.npz", {}, "is not a folder"),
        (lambda p: (p / "file").write_text("x") and p / "file", {"folder": True}, "exists and is not a folder"),
    ],
)
def test_check_output_names_the_option_the_path_and_the_problem(tmp_path, make, kwargs, message):
    """Each bad target raises OutputError (an OSError and a ValueError) with option, path and reason."""
    path = make(tmp_path)
    with pytest.raises(OutputError, match=message) as info:
        check_output(path, option="--record", **kwargs)
    assert str(info.value).startswith(f"--record {str(path)!r}")
    assert isinstance(info.value, OSError) and isinstance(info.value, ValueError)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_check_output_probes_the_folder(tmp_path):
    """A folder without write permission is refused by the probe, not by the permission bits."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(OutputError, match="cannot write in"):
            check_output(locked / "run.npz")
    finally:
        locked.chmod(0o700)


def test_check_folder_needs_an_existing_folder(tmp_path):
    """check_folder accepts a folder and refuses a missing path or a file."""
    assert check_folder(tmp_path, option="--out-dir") == tmp_path
    with pytest.raises(OutputError, match="no such directory"):
        check_folder(tmp_path / "missing", option="--out-dir")
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="is not a folder"):
        check_folder(tmp_path / "file", option="--out-dir")


def test_atomic_path_replaces_the_file_only_when_the_block_succeeds(tmp_path):
    """Success: the new content, with the old file's mode. Failure: the old file as it was, no temporary left."""
    target = tmp_path / "out.npz"
    target.write_text("old")
    target.chmod(0o640)
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".npz" and tmp != target
        tmp.write_text("new")
        assert target.read_text() == "old"  # untouched until the block ends
    assert target.read_text() == "new"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    with pytest.raises(KeyboardInterrupt), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.npz"]


def test_atomic_path_turns_an_os_error_into_an_output_error(tmp_path):
    """An OSError inside the block (a full disk) is re-raised as OutputError naming the target."""
    target = tmp_path / "out.gif"
    with pytest.raises(OutputError, match="cannot write .*out.gif.*No space left"), atomic_path(target):
        raise OSError(28, "No space left on device")
    assert list(tmp_path.iterdir()) == []


def test_atomic_file_commits_or_discards(tmp_path):
    """An AtomicFile kept open across calls becomes the target on commit, and leaves nothing on discard."""
    keep = AtomicFile(tmp_path / "clip.mp4")
    keep.tmp.write_bytes(b"video")
    assert keep.commit() == tmp_path / "clip.mp4"
    drop = AtomicFile(tmp_path / "other.mp4")
    drop.tmp.write_bytes(b"partial")
    drop.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.mp4"]
    assert (tmp_path / "clip.mp4").read_bytes() == b"video"


def test_atomic_folder_creates_or_updates_a_frame_folder(tmp_path):
    """A new folder appears whole; rewriting one drops stale numbered frames (frame_ and five or more
    digits, as Tumble writes them) and keeps every other file, a user's frame_cover.png or frame_0001.png too."""
    frames = tmp_path / "frames"
    with atomic_folder(frames) as tmp:
        for k in range(3):
            (tmp / f"frame_{k:05d}.png").write_bytes(b"%d" % k)
        assert not frames.exists()
    assert sorted(p.name for p in frames.iterdir()) == ["frame_00000.png", "frame_00001.png", "frame_00002.png"]
    for name in ("notes.txt", "frame_cover.png", "frame_0001.png"):
        (frames / name).write_text("mine")
    with atomic_folder(frames) as tmp:
        (tmp / "frame_00000.png").write_bytes(b"new")
    assert sorted(p.name for p in frames.iterdir()) == [
        "frame_00000.png",
        "frame_0001.png",
        "frame_cover.png",
        "notes.txt",
    ]
    assert (frames / "frame_00000.png").read_bytes() == b"new"
    with pytest.raises(RuntimeError), atomic_folder(frames) as tmp:
        (tmp / "frame_00000.png").write_bytes(b"broken")
        raise RuntimeError("encoder failed")
    assert (frames / "frame_00000.png").read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]

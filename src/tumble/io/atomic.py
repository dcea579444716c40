"""Writing files so that a failure never costs the user a file: check first, write beside, rename.

Every file Tumble writes (recordings, videos, GIFs, PNG frame folders, plots) goes through
this module:

- `check_output(path, ...)` is called before any simulation starts: the suffix is one the
  command knows, the folder exists and is a folder, a file target is not a directory, and a
  probe file can really be created there (permission bits say little when running as root).
- `atomic_path(path)` yields a temporary path beside `path` (same folder, so the same file
  system; same suffix, so tools that go by the extension still work). When the block succeeds
  the file is flushed to disk and renamed onto `path` with `os.replace`, which is atomic; when
  it fails (a full disk, Ctrl-C, an encoder error) the temporary file is removed. Either way
  an existing `path` is untouched until the new file is complete.
- `atomic_folder(path)` does the same for a folder of numbered frames.

Typical use::

    check_output("pile.npz", suffixes=(".npz",), option="--record")   # before simulating
    ...
    with atomic_path("pile.npz") as tmp:
        np.savez_compressed(tmp, **arrays)
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

from ..errors import TumbleError


class OutputError(TumbleError, OSError, ValueError):
    """An output path Tumble cannot write; the message names the path and why.

    An OSError, and a ValueError as the checks it replaces were (`Recorder.save`, `plot_record`).
    """


def check_output(path, *, suffixes: Sequence[str] = (), folder: bool = False, option: str = "-o") -> Path:
    """Check, before any work, that `path` can be written; returns it as a Path.

    Args:
        path: the file (or, with `folder`, the folder) to write.
        suffixes: the file suffixes allowed (lower case, with the dot); empty allows any.
        folder: `path` is a folder of frames: it may exist (as a folder) or be created.
        option: the command-line option that gave `path`, named in messages.

    Raises:
        OutputError: naming the option, the path and what is wrong.
    """
    p = Path(path)
    where = f"{option} {str(path)!r}" if option else repr(str(path))
    if folder:
        if p.exists() and not p.is_dir():
            raise OutputError(f"{where}: exists and is not a folder")
    else:
        if suffixes and p.suffix.lower() not in suffixes:
            raise OutputError(f"{where}: the file name must end in {' or '.join(suffixes)}")
        if p.is_dir():
            raise OutputError(f"{where}: is a directory, not a file")
    parent = p.parent
    if not parent.exists():
        raise OutputError(f"{where}: no such directory {str(parent)!r}")
    if not parent.is_dir():
        raise OutputError(f"{where}: {str(parent)!r} is not a folder")
    probe_folder(parent, where)
    if folder and p.is_dir():
        probe_folder(p, where)
    return p


def check_folder(path, *, option: str) -> Path:
    """Check that `path` is an existing folder Tumble can create files in (e.g. `view --out-dir`)."""
    p = Path(path)
    where = f"{option} {str(path)!r}"
    if not p.is_dir():
        raise OutputError(f"{where}: {'is not a folder' if p.exists() else 'no such directory'}")
    probe_folder(p, where)
    return p


def probe_folder(folder: Path, where: str) -> None:
    """Create and remove a file in `folder`, the only reliable test that it is writable (an existing
    file there need not be: it is replaced by a rename). Raises OutputError "{where}: cannot write in ..."."""
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".tumble-probe-")
        os.close(fd)
        os.unlink(name)
    except OSError as exc:
        raise OutputError(f"{where}: cannot write in {str(folder)!r} ({exc.strerror or exc})") from None


def _file_mode(target: Path) -> int:
    """Permissions for a new file at `target`: the existing file's, else 0o666 less the umask."""
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        return 0o666 & ~_umask()


def _fsync(path: Path) -> None:
    with open(path, "rb") as f:
        os.fsync(f.fileno())


class AtomicFile:
    """A temporary file beside `path` that becomes `path` on `commit()` (for writers that stay open).

    `atomic_path` is the same as a `with` block; a writer that lives across calls (the viewer's
    video recording) makes one, writes to `.tmp`, then calls `commit()` or `discard()`.
    """

    def __init__(self, path):
        self.path = Path(path)
        fd, name = tempfile.mkstemp(
            dir=self.path.parent, prefix=f".{self.path.name}.", suffix=f".tmp{self.path.suffix}"
        )
        os.close(fd)
        self.tmp = Path(name)

    def commit(self) -> Path:
        """Flush the temporary file to disk and rename it onto `path` (atomic). Returns `path`."""
        try:
            os.chmod(self.tmp, _file_mode(self.path))
            _fsync(self.tmp)
            os.replace(self.tmp, self.path)
        except OSError as exc:
            self.discard()
            raise OutputError(f"cannot write {str(self.path)!r}: {exc.strerror or exc}") from exc
        return self.path

    def discard(self) -> None:
        """Remove the temporary file; `path` stays as it was."""
        with contextlib.suppress(OSError):
            self.tmp.unlink()


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a temporary path beside `path`; rename it onto `path` when the block succeeds.

    On any exception (KeyboardInterrupt included) the temporary file is removed and `path` is
    left as it was. An OSError is re-raised as `OutputError` naming `path`.
    """
    file = AtomicFile(path)
    try:
        yield file.tmp
    except BaseException as exc:
        file.discard()
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(f"cannot write {str(file.path)!r}: {exc.strerror or exc}") from exc
        raise
    file.commit()


@contextlib.contextmanager
def atomic_folder(path, *, frames: str = r"frame_\d{5,}\.png") -> Iterator[Path]:
    """Yield a temporary folder beside `path`; when the block succeeds its files become `path`.

    A new `path` is the temporary folder renamed. An existing folder gets each new file by
    `os.replace`, and its files whose whole name matches the regular expression `frames` (the
    numbered frames Tumble writes, frame_00042.png) that the new set lacks (frames of a longer
    earlier render) are removed; other files in it (a user's frame_cover.png or frame_0001.png
    too) are left alone. On failure the temporary folder is removed and `path` is untouched.
    """
    numbered = re.compile(frames)
    target = Path(path)
    tmp = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp"))
    try:
        yield tmp
        for f in tmp.iterdir():
            _fsync(f)
        if not target.exists():
            os.chmod(tmp, 0o777 & ~_umask())
            os.rename(tmp, target)
            return
        new = {f.name for f in tmp.iterdir()}
        for name in sorted(new):
            os.replace(tmp / name, target / name)
        for old in target.iterdir():
            if old.name not in new and numbered.fullmatch(old.name) and old.is_file():
                old.unlink()
        tmp.rmdir()
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(f"cannot write {str(target)!r}: {exc.strerror or exc}") from exc
        raise


def _umask() -> int:
    """The process's umask (read by setting and restoring it)."""
    umask = os.umask(0)
    os.umask(umask)
    return umask

"""Unit tests of tumble.io, one file per module."""

from pathlib import Path


def record_scene(path: Path, text: str, frames: int, fps: float) -> dict:
    """Write scene `text` to `path`, record `frames` frames of it at `fps` beside it (take.npz), and
    return the recording as `load_recording` reads it back."""
    import tumble
    from tumble.io.record import Recorder, load_recording

    path.write_text(text, encoding="utf-8")
    world = tumble.load_scene(path)
    recorder = Recorder(world, fps=fps)
    while recorder.frame_count < frames:
        world.step()
        recorder(world)
    npz = path.with_name("take.npz")
    recorder.save(npz)
    return load_recording(npz)


#: stages opened by the tests, kept alive while their prims are in use (a prim dies with its stage)
_OPEN_STAGES: list = []


def open_stage(path):
    """The USD stage at `path` (pxr), kept open for the rest of the session."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    _OPEN_STAGES.append(stage)
    return stage


def validation_errors(path) -> list[str]:
    """What USD's own validators (every one `pxr.UsdValidation` registers: stage metadata, composition,
    attribute types, UsdGeom, UsdShade and UsdPhysics rules, packages) report of the stage at
    `path`: one "name: message" line each, none for a clean stage."""
    from pxr import UsdValidation

    registry = UsdValidation.ValidationRegistry()
    context = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    return [f"{e.GetName()}: {e.GetMessage()}" for e in context.Validate(open_stage(path))]

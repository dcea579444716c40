"""A perspective look-at camera with the orbit, pan, zoom and framing moves a viewer needs.

World units are metres and +z is up by default (gravity along -z). Matrices follow OpenGL
conventions: the view looks down -z in eye space and clip depth runs from -1 (near) to 1 (far).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .. import validate
from ..shapes import ShapeType

#: default vertical field of view [degrees]: about a 50 mm lens. Perspective stretches a sphere
#: at angle a off the view axis by 1 / cos(a) along the radial direction; at 25 degrees and 16:9
#: that is 7.5 % at the left and right edges (45 degrees gave 30 %)
DEFAULT_FOV = 25.0
#: farthest from the origin a camera or its target may be [m]: the renderer's matrices are float32,
#: whose products of coordinates overflow past ~1e19 m (1e300 ended in "Singular matrix")
MAX_COORDINATE = 1e12
#: direction from the target to the camera used when there is no better one (front, right, above)
DEFAULT_DIRECTION = np.array([0.55, -1.0, 0.5])


def _normalize(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else v


class Camera:
    """Perspective camera looking from `position` at `target`.

    Args:
        position: eye position [m], shape (3,).
        target: point looked at (the orbit centre) [m], shape (3,).
        up: world direction that appears upward on screen, shape (3,).
        fov_deg: vertical field of view [degrees], in (0, 180).
        near, far: clip distances [m]; None picks them from the distance to the target.
    """

    def __init__(
        self,
        position: Sequence[float] | np.ndarray = (2.2, -4.0, 2.0),
        target: Sequence[float] | np.ndarray = (0.0, 0.0, 0.3),
        up: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
        fov_deg: float = DEFAULT_FOV,
        *,
        near: float | None = None,
        far: float | None = None,
    ):
        self.position = validate.vector(position, "camera position")
        self.target = validate.vector(target, "camera target")
        for name, v in (("camera position", self.position), ("camera target", self.target)):
            if np.max(np.abs(v)) > MAX_COORDINATE:
                raise ValueError(
                    f"{name} must be within {MAX_COORDINATE:g} m of the origin, got {validate.show(v.tolist())}"
                )
        self.up = validate.direction(up, "camera up")
        self.fov_deg = validate.number(fov_deg, "camera field of view", low=0.0, high=180.0, above=True, below=True)
        self.near = near
        self.far = far
        #: height along `up` [m] the eye never goes below in `orbit`, `pan` and `zoom` (the
        #: viewer sets it to its ground plane); None: no limit
        self.floor: float | None = None
        if np.linalg.norm(self.position - self.target) < 1e-9:
            raise ValueError("camera position and target must differ")

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_dict(cls, spec: dict) -> Camera:
        """Camera from a scene's `[camera]` table: keys `position`, `target`, `fov` (degrees), `up`.

        Missing keys keep the defaults.
        """
        if not isinstance(spec, dict):
            raise ValueError(f"camera must be a table with position, target and fov, got {spec!r}")
        kwargs = {}
        for key in ("position", "target", "up"):
            if spec.get(key) is not None:
                kwargs[key] = spec[key]
        fov = spec.get("fov", spec.get("fov_deg"))
        if fov is not None:
            kwargs["fov_deg"] = fov
        return cls(**kwargs)

    @classmethod
    def for_world(cls, world, *, aspect: float = 16 / 9) -> Camera:
        """The camera a world asks for (`world.metadata["camera"]`), else one framing the scene.

        A metadata camera that gives a position but no target looks at the framed scene's centre;
        one that gives a target but no position keeps the default viewing direction.
        """
        spec = getattr(world, "metadata", {}).get("camera") if world is not None else None
        cam = cls()
        if spec:
            cam = cls.from_dict(spec)
            if spec.get("position") is not None and spec.get("target") is not None:
                return cam
        framed = cls(up=cam.up, fov_deg=cam.fov_deg)
        framed.frame(world, aspect=aspect)
        if spec and spec.get("position") is not None:
            framed.position = cam.position
            if np.linalg.norm(framed.position - framed.target) < 1e-9:
                framed.target = framed.target - framed.up
        elif spec and spec.get("target") is not None:
            offset = framed.position - framed.target
            framed.target = cam.target
            framed.position = cam.target + offset
        return framed

    def copy(self) -> Camera:
        """An independent copy (e.g. to keep as the reset view)."""
        cam = Camera(self.position, self.target, self.up, self.fov_deg, near=self.near, far=self.far)
        cam.floor = self.floor
        return cam

    def to_dict(self) -> dict:
        """The camera as a scene-file `[camera]` table."""
        return {
            "position": [float(v) for v in self.position],
            "target": [float(v) for v in self.target],
            "up": [float(v) for v in self.up],
            "fov": float(self.fov_deg),
        }

    def __repr__(self) -> str:
        p, t = np.round(self.position, 4).tolist(), np.round(self.target, 4).tolist()
        return f"Camera(position={p}, target={t}, fov_deg={self.fov_deg:g})"

    # ------------------------------------------------------------------ frame of the eye

    @property
    def distance(self) -> float:
        """Distance from the eye to the target [m]."""
        return float(np.linalg.norm(self.position - self.target))

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors (right, up, forward) of the eye in world coordinates."""
        forward = _normalize(self.target - self.position)
        right = np.cross(forward, self.up)
        if np.linalg.norm(right) < 1e-9:  # looking straight along up: pick any right
            right = np.cross(forward, np.array([1.0, 0.0, 0.0]))
            if np.linalg.norm(right) < 1e-9:
                right = np.cross(forward, np.array([0.0, 1.0, 0.0]))
        right = _normalize(right)
        return right, np.cross(right, forward), forward

    def clip_range(self) -> tuple[float, float]:
        """(near, far) clip distances [m]: the given ones, else scaled by the target distance."""
        d = max(self.distance, 1e-3)
        near = self.near if self.near is not None else max(1e-3, 0.01 * d)
        far = self.far if self.far is not None else max(200.0 * d, 50.0)
        return float(near), float(far)

    def view_matrix(self) -> np.ndarray:
        """World -> eye transform, shape (4, 4), float64 (row-major: multiply column vectors)."""
        right, up, forward = self.basis()
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = right, up, -forward
        m[:3, 3] = -m[:3, :3] @ self.position
        return m

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """Eye -> clip transform (OpenGL perspective), shape (4, 4), float64."""
        near, far = self.clip_range()
        f = 1.0 / math.tan(math.radians(self.fov_deg) / 2.0)
        m = np.zeros((4, 4))
        m[0, 0] = f / aspect
        m[1, 1] = f
        m[2, 2] = (far + near) / (near - far)
        m[2, 3] = 2.0 * far * near / (near - far)
        m[3, 2] = -1.0
        return m

    def view_projection(self, aspect: float) -> np.ndarray:
        """World -> clip transform, shape (4, 4), float64."""
        return self.projection_matrix(aspect) @ self.view_matrix()

    def project(self, points, width: int, height: int) -> np.ndarray:
        """Pixel coordinates of world points in a `width` x `height` image.

        Args:
            points: world points [m], shape (3,) or (n, 3).

        Returns:
            (x, y, depth) per point, shape (n, 3) (or (3,)): x to the right and y downward in
            pixels from the top-left corner (row = int(y), column = int(x)), depth the distance
            along the view direction [m] (negative behind the eye).
        """
        p = np.asarray(points, dtype=np.float64)
        single = p.ndim == 1
        p = np.atleast_2d(p)
        clip = np.c_[p, np.ones(len(p))] @ self.view_projection(width / height).T
        w = clip[:, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (clip[:, 0] / w * 0.5 + 0.5) * width
            y = (0.5 - clip[:, 1] / w * 0.5) * height
        out = np.stack([x, y, w], axis=1)
        return out[0] if single else out

    def ray(self, x: float, y: float, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """World ray through pixel (x, y) (from the top-left, as `project` gives): (origin, unit direction)."""
        right, up, forward = self.basis()
        t = math.tan(math.radians(self.fov_deg) / 2.0)
        sx = (2.0 * x / width - 1.0) * t * width / height
        sy = (1.0 - 2.0 * y / height) * t
        return self.position.copy(), _normalize(forward + sx * right + sy * up)

    # ------------------------------------------------------------------ moves

    def orbit(self, dx: float, dy: float) -> None:
        """Turn the eye around the target: `dx` radians about `up` (yaw), `dy` radians of elevation.

        Positive `dx` moves the eye to the right around the target and positive `dy` raises it;
        the elevation stops 1 degree short of straight up or down. A viewer maps a mouse drag of
        (px, py) pixels to e.g. `orbit(-px * 0.01, py * 0.01)`.
        """
        offset = self.position - self.target
        r = float(np.linalg.norm(offset))
        up = self.up
        # elevation angle of the offset above the plane normal to `up`
        elevation = math.asin(max(-1.0, min(1.0, float(np.dot(offset, up)) / r)))
        horizontal = offset - np.dot(offset, up) * up
        if np.linalg.norm(horizontal) < 1e-9 * r:
            horizontal = self.basis()[1] * -np.sign(np.dot(offset, up) or 1.0)
        horizontal = _normalize(horizontal)
        side = np.cross(up, horizontal)
        # yaw: rotate the horizontal direction about up (Rodrigues' formula in the up-normal plane)
        horizontal = _normalize(math.cos(dx) * horizontal + math.sin(dx) * side)
        limit = math.radians(89.0)
        lowest = -limit
        if self.floor is not None:
            # the eye stays above the floor: sin(elevation) >= (floor + clearance - target height) / r
            above = (self._eye_floor(r) - float(np.dot(self.target, up))) / r
            lowest = max(lowest, math.asin(max(-1.0, min(1.0, above)))) if above < 1.0 else limit
        elevation = max(lowest, min(limit, elevation + dy))
        self.position = self.target + r * (math.cos(elevation) * horizontal + math.sin(elevation) * up)

    def pan(self, dx: float, dy: float) -> None:
        """Slide eye and target sideways: `dx`, `dy` are fractions of the view's height at the target.

        Positive `dx` moves the view content left (the camera right), positive `dy` moves the
        camera up. A viewer maps a drag of (px, py) pixels to `pan(-px / h, py / h)` so that the
        point under the cursor follows it.
        """
        right, up, _ = self.basis()
        visible = 2.0 * self.distance * math.tan(math.radians(self.fov_deg) / 2.0)
        shift = (dx * right + dy * up) * visible
        if self.floor is not None:
            # slide no lower than the floor allows (the sideways part of the move stays)
            low = self._eye_floor(self.distance) - float(np.dot(self.position + shift, self.up))
            if low > 0.0:
                shift = shift + min(low, max(0.0, -float(np.dot(shift, self.up)))) * self.up
        self.position = self.position + shift
        self.target = self.target + shift

    def zoom(self, factor: float) -> None:
        """Move the eye towards the target: the distance is divided by `factor` (> 1 zooms in)."""
        factor = validate.positive(factor, "zoom factor")
        offset = (self.position - self.target) / factor
        d = float(np.linalg.norm(offset))
        if d < 1e-4:
            offset *= 1e-4 / d
        elif d > 1e6:
            offset *= 1e6 / d
        if self.floor is not None:
            # zooming out while looking up stops where the eye would reach the floor
            drop = -float(np.dot(offset, self.up))
            room = float(np.dot(self.target, self.up)) - self._eye_floor(float(np.linalg.norm(offset)))
            if drop > 0.0 and 0.0 < room < drop:
                offset *= room / drop
        self.position = self.target + offset

    def _eye_floor(self, distance: float) -> float:
        """The lowest eye height allowed: the floor plus 1 cm or 2 % of the target distance."""
        assert self.floor is not None  # called only where a floor is set
        return float(self.floor) + max(0.01, 0.02 * distance)

    def frame(self, world, *, aspect: float = 16 / 9, margin: float = 1.15, direction=None) -> None:
        """Aim at and fit every non-plane body and the cloth (and emitters' sources) in view.

        Keeps the current viewing direction unless `direction` (target -> eye) is given. With
        nothing to frame, looks at the origin from a few metres away.
        """
        centre, radius = scene_bounds(world)
        d = self.position - self.target if direction is None else validate.vector(direction, "camera direction")
        if np.linalg.norm(d) < 1e-9:
            d = DEFAULT_DIRECTION
        d = _normalize(d)
        half = math.radians(self.fov_deg) / 2.0
        # the bounding sphere fits when its radius subtends the smaller half field of view
        half_min = min(half, math.atan(math.tan(half) * aspect))
        dist = margin * radius / math.sin(half_min)
        self.target = centre
        self.position = centre + d * max(dist, 1e-3)


def ground_level(world) -> float | None:
    """Height [m] of the highest level plane (normal +z) of a world, or None when it has none."""
    if world is None or not world.body_count:
        return None
    shape = np.asarray(world.body_shape)
    level = np.flatnonzero((shape == ShapeType.PLANE) & (np.asarray(world.body_plane_normal)[:, 2] > 0.99))
    if not len(level):
        return None
    return float(np.max(np.asarray(world.body_position)[level, 2]))


def scene_box(world) -> tuple[np.ndarray, np.ndarray] | None:
    """Axis-aligned box (lo, hi) [m] around all non-plane bodies, cloth and emitter regions; None if empty."""
    lo, hi = [], []
    if world is not None and world.body_count:
        shape = np.asarray(world.body_shape)
        keep = shape != ShapeType.PLANE
        pos = np.asarray(world.body_position)[keep]
        r = np.where(shape == ShapeType.SPHERE, world.body_radius, np.linalg.norm(world.body_half_extents, axis=1))
        r = r[keep]
        ok = np.all(np.isfinite(pos), axis=1)
        if ok.any():
            lo.append((pos[ok] - r[ok, None]).min(axis=0))
            hi.append((pos[ok] + r[ok, None]).max(axis=0))
    if world is not None and world.has_cloth:
        p = np.asarray(world.cloth.particle_position, dtype=np.float64).reshape(-1, 3)
        p = p[np.all(np.isfinite(p), axis=1)]
        if len(p):
            lo.append(p.min(axis=0))
            hi.append(p.max(axis=0))
    for emitter in getattr(world, "emitters", None) or []:
        pos = getattr(emitter, "position", None)
        if pos is None:
            continue
        try:
            pos = np.asarray(pos, dtype=np.float64).reshape(3)
            ext = np.abs(np.asarray(getattr(emitter, "extent", 0.0) or 0.0, dtype=np.float64)).reshape(-1)
        except (TypeError, ValueError):
            continue
        ext = np.broadcast_to(ext[:3] if ext.size >= 3 else ext[:1], (3,))
        lo.append(pos - ext)
        hi.append(pos + ext)
    if not lo:
        return None
    return np.min(lo, axis=0), np.max(hi, axis=0)


def scene_bounds(world) -> tuple[np.ndarray, float]:
    """Centre [m] and radius [m] of a sphere around all non-plane bodies, cloth and emitters.

    Returns ((0, 0, 0.5), 1.5) for an empty scene.
    """
    box = scene_box(world)
    if box is None:
        return np.array([0.0, 0.0, 0.5]), 1.5
    lo, hi = box
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 0.05)
    return centre, radius

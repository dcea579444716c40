"""A mixed scene: spheres and tumbling boxes rain into a walled static-box floor split by a thin wall."""

from __future__ import annotations

import numpy as np

import tumble


def test_mixed_rain_stays_on_the_floor_and_out_of_the_wall():
    """Nothing passes through the floor, the 4 cm wall or the walls around, nothing overlaps deeply."""
    w = tumble.World(seed=5)
    w.add_box(position=(0, 0, -0.5), half_extents=(3, 3, 0.5), static=True, friction=0.6, restitution=0.2)
    w.add_box(position=(0, 0, 0.3), half_extents=(0.02, 2, 0.3), static=True)
    for x, y, hx, hy in ((3.1, 0, 0.1, 3.2), (-3.1, 0, 0.1, 3.2), (0, 3.1, 3.2, 0.1), (0, -3.1, 3.2, 0.1)):
        w.add_box(position=(x, y, 0.5), half_extents=(hx, hy, 0.5), static=True)
    w.add_emitter(
        shape=["sphere", "box"],
        rate=600,
        count=300,
        position=(0, 0, 2),
        region="box",
        extent=(1, 1, 0.3),
        speed=(0, 3),
        cone_angle=30,
        radius=(0.03, 0.08),
        half_extents=(0.03, 0.07),
        random_orientation=True,
        angular_speed=(0, 10),
        restitution=0.2,
        friction=0.6,
    )
    w.run(3.0)
    x = w.body_position[6:]
    assert w.body_count == 306
    assert np.isfinite(x).all()
    # on the floor (top at z = 0), within its extent, none inside the wall
    assert x[:, 2].min() > 0.0
    assert np.abs(x[:, :2]).max() < 3.0
    in_wall = (np.abs(x[:, 0]) < 0.02) & (np.abs(x[:, 1]) < 2.0) & (x[:, 2] < 0.6)
    assert not in_wall.any()
    w.collide()
    assert w.contact_depth.max() < 5e-3
    # Boxes have come to rest, but for those that rolling spheres move. The spheres have no rolling
    # resistance and still roll at 3 s (up to 1.7 m/s), so a box they strike, or a box resting on
    # two of them (a line of support it topples off as they roll), moves at any time: with the
    # world's seed changed, 2 to 4 of 24 seeds had a box moving at 3 s (0.12 to 1.16 m/s), each in
    # contact with a sphere. So the boxes joined to a sphere by contacts, through other dynamic
    # bodies, are left out, and every other box is at rest (42 to 63 of about 155 in those runs).
    speed = np.linalg.norm(w.body_velocity, axis=1)
    boxes = w.body_shape == tumble.ShapeType.BOX
    boxes[:6] = False
    pair = w.contact_pair
    moved = w.body_shape == tumble.ShapeType.SPHERE  # bodies a rolling sphere can move
    while True:
        touching = moved[pair[:, 0]] | moved[pair[:, 1]]
        reached = moved.copy()
        reached[pair[touching].ravel()] = True
        reached[:6] = False  # the static floor and walls pass on no motion
        if (reached == moved).all():
            break
        moved = reached
    still = boxes & ~moved
    assert still.sum() >= 30
    assert speed[still].max() < 0.1
    assert speed[6:].max() < 2.0

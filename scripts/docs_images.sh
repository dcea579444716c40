#!/usr/bin/env bash
# Render the pictures of the docs: every sample's GIF (docs/rendering.md) and the README's
# animation. Run from the repository root; takes some minutes on a CPU (EGL, Mesa llvmpipe).
#
#   ./scripts/docs_images.sh            # all of them
#   ./scripts/docs_images.sh readme     # only docs/images/readme.gif
set -euo pipefail
cd "$(dirname "$0")/.."
tumble() { python -m tumble "$@"; }

# the README's first screen: balls dropped into a hammock, 3 s at 12 fps, 384 x 216
tumble render samples/hammock.toml -o docs/images/readme.gif --size 384x216 --fps 12 --duration 3 --no-progress
[ "${1:-}" = "readme" ] && exit 0

for name in bouncing_ball rolling_ball friction_slide ramp box_tower pyramid rain sphere_pile \
            cloth_drape flag hammock pebbles pebble_bowl capsule_slope cloth_statue; do
    tumble render "samples/$name.toml" -o "docs/images/$name.gif" --size 320x180 --fps 12 --duration 3 --no-progress
done
# the joint samples, with their joints drawn
for name in newtons_cradle rope_bridge ragdoll_stairs flag_pole; do
    tumble render "samples/$name.toml" -o "docs/images/$name.gif" --size 320x180 --fps 12 --duration 3 --joints \
        --no-progress
done
# capsules, hulls and a static mesh (docs/rendering.md)
python scripts/shapes_picture.py docs/images/rendering_shapes.png

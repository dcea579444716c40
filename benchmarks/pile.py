"""The sphere-pile benchmark of issue 2: Tumble alone, 1,000, 5,000 and 20,000 spheres.

    PYTHONPATH=src python benchmarks/pile.py [--device cuda] [--duration S]

Prints steps per second and body-steps per second for each pile (and the quality figures);
it is `run.py --scenes pile --engines tumble` and takes the same options.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.run import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(["--scenes", "pile", "--engines", "tumble", *sys.argv[1:]]))

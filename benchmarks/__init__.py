"""Benchmarks of Tumble against PyBullet and MuJoCo; run `python benchmarks/run.py --help`."""

"""`python -m tumble ...`: the `tumble` command, for environments whose scripts are not on PATH."""

import sys

from .cli import main

if __name__ == "__main__":  # importing the module (as tools that walk the package do) runs nothing
    sys.exit(main())

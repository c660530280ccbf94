"""The `tsim` command of the Python package: the tsim binary's command line, in-process."""

import os
import sys

from . import _tsim


def main():
    # `tsim figures` runs the figures script with TSIM_PYTHON: this interpreter, which has
    # the package's dependencies, unless the user named another.
    os.environ.setdefault("TSIM_PYTHON", sys.executable)
    sys.exit(_tsim.cli(["tsim", *sys.argv[1:]]))


if __name__ == "__main__":
    main()

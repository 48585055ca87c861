"""The ``gcm-ortho`` command, as the package installs it."""

import sys

from . import _native


def main() -> None:
    sys.exit(_native.command(sys.argv))


if __name__ == "__main__":
    main()

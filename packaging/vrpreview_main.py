"""Entry point of the PyInstaller bundle: the same ``vrpreview`` command as the wheel's script."""

import sys

from ui.launcher import main

if __name__ == "__main__":
    sys.exit(main())

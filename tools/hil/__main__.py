"""``python -m tools.hil``: see tools/hil/cli.py and docs/hil.md."""
import os
import sys

from tools.hil.cli import main

try:
    sys.exit(main())
except BrokenPipeError:  # output piped into e.g. `head`: not an error of the run
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    sys.exit(0)

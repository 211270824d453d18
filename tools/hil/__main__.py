"""``python -m tools.hil``: see tools/hil/cli.py and docs/hil.md."""
import sys

from tools.hil.cli import main

sys.exit(main())

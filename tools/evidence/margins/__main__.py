"""``python -m tools.evidence.margins``: how much gain, phase and delay can the loop lose?
The finders and the command line are tools.evidence.margins.inproc (in process) and
tools.evidence.margins.wire (over the wire)."""
from tools.evidence.margins.inproc import main

raise SystemExit(main())

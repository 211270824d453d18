"""``python -m tools.relay``: the seeded UDP impairment relay as a process of its own (loss,
delay, jitter, duplicates, reordering, frame delay). The relay and its command line are the
harness's library tools.sitl.linkimpair (``RelayProcess`` starts this command)."""
from tools.sitl.linkimpair import main

if __name__ == "__main__":
    raise SystemExit(main())

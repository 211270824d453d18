"""tools.evidence.margins: how much gain, phase and delay can the loop lose?

- ``inproc``: the loop broken at the actuator input in process (the injection block, the
  margin finders, the tables) and the command line ``python -m tools.evidence.margins``;
- ``wire``: the time-delay margin over the wire (lockstep frames or real-time ms through the
  impairment relay); also the plant-wrapper process ``python -m tools.evidence.margins.wire``
  that the runner starts;
- ``flight``: one injected flight and its stability verdict, shared by both.
"""

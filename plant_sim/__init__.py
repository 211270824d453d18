"""plant_sim: the winged-cone hypersonic plant simulator (docs/plant.md).

Run as a process with ``python -m plant_sim`` (MAVLink over UDP, docs/wire.md), or in process
with ``plant_sim.sim.PlantSim`` and the njit kernels of ``plant_sim.dynamics`` (docs/plant.md,
"In-process API"). Importing the package imports nothing heavy.
"""

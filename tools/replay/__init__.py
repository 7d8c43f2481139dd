"""Offline replay of recorded drives through the onboard sensor: run tables (``table``: the sensor's per-step inputs
from a CSV) and CAN logs (``log``: through the live CAN service, frame by frame or the whole log at once), and the
plot of a replay (``plot``). The command line (``gearbox-vsensor replay``, tools/cli/replay.py) only parses its
arguments and calls these."""

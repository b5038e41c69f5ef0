"""The propeller hardware choice, in one place: how much thrust each motor pair gives in reverse.

The command-to-motion latency target (100 ms) is a requirement on the system, and the
physics (``latency_floor.py``, ``docs/flight.md``) shows that one-direction propellers on
the horizontal pair cannot meet it backward: their 60 % reverse thrust through the 80 ms
motor lag reaches 2 cm/s only after about 119 ms even at full authority. So the hardware
spec (``docs/motor-board.md``) is: the two horizontal (thrust/yaw) motors carry reversible
3D (symmetric-pitch) propellers on reversible (3D-mode) ESCs; the two vertical motors keep
one-direction propellers, mounted so their efficient direction pushes the body down, which
is their steady job against the net buoyancy.

The config defaults (``[flight]``) and the simulated body (``BlimpParams``) both start
from these numbers, so the controller's knowledge and the simulator agree by default.
"""

from __future__ import annotations

# A 3D propeller's blades are symmetric, so the blade makes the same thrust both ways;
# what is left is the installation (the motor bell and mount sit in the inflow one way and
# in the wake the other) and the ESC. 5 % is an allowance for that, to be measured on a
# thrust stand with the propeller in its pod (docs/blimp-simulator.md).
REVERSIBLE_3D_REVERSE_RATIO = 0.95

# A propeller pitched for one direction, driven backwards: its cambered blades meet the
# air with their trailing edge first and give roughly 60 % of the forward thrust.
ONE_DIRECTION_REVERSE_RATIO = 0.6

"""The names code uses for what ships with dynid: the demo's default vehicle (vehicle/vehicles/<name>.toml) and the
car template's name in a config (`[model] template = ...`). A leaf: `dynid --help` reads the defaults from here
without loading the vehicle layer."""

from __future__ import annotations

DEMO_VEHICLE = "peugeot406"  # the vehicle a command or a config uses when none is given
CAR_TEMPLATE = DEMO_VEHICLE  # the paper's 42-frame car, named after the car it was written for; alone: that car

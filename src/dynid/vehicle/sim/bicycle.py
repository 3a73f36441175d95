"""The linear bicycle model of the same car: axle cornering stiffnesses and understeer gradient.

From the static axle loads (rest state) and the tire's cornering stiffness at each
wheel's static load (MagicFormula.cornering_stiffness), with L the wheelbase, m_f, m_r
the axle loads as masses (Fz / g) and C_f, C_r the axle cornering stiffnesses:

  understeer gradient  K = m_f / C_f - m_r / C_r          rad per m/s^2 (road-wheel angle)
  yaw-rate gain        r / delta = v / (L + K v^2)
  steady steer         delta = (L / v^2 + K) a_y

and, with the yaw inertia Iz and the centre of mass a = L m_r / m behind the front axle,
the 2-DOF (lateral velocity, yaw rate) frequency response a_y / delta at f Hz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Bicycle:
    wheelbase: float
    mass_front: float
    mass_rear: float
    cf: float
    cr: float
    yaw_inertia: float = 0.0

    @property
    def mass(self) -> float:
        return self.mass_front + self.mass_rear

    @property
    def understeer(self) -> float:
        return self.mass_front / self.cf - self.mass_rear / self.cr

    def yaw_rate_gain(self, v: float) -> float:
        """r / delta (1/s) at speed v (m/s), delta the road-wheel angle."""
        return v / (self.wheelbase + self.understeer * v * v)

    def steer_for(self, v: float, ay: float) -> float:
        return (self.wheelbase / v**2 + self.understeer) * ay

    def lateral_gain(self, v: float, f: float) -> float:
        """|a_y / delta| (m/s^2 per rad) of the 2-DOF model at f Hz (f = 0: steady state)."""
        m, L, Cf, Cr = self.mass, self.wheelbase, self.cf, self.cr
        a = L * self.mass_rear / m
        b = L - a
        Iz = self.yaw_inertia
        A = np.array([[-(Cf + Cr) / (m * v), -(a * Cf - b * Cr) / (m * v) - v],
                      [-(a * Cf - b * Cr) / (Iz * v), -(a * a * Cf + b * b * Cr) / (Iz * v)]])
        B = np.array([Cf / m, a * Cf / Iz])
        s = 2j * np.pi * f
        x = np.linalg.solve(s * np.eye(2) - A, B)
        return float(abs(s * x[0] + v * x[1]))


def bicycle(loads: np.ndarray, tires, wheelbase: float, g: float = 9.81, yaw_inertia: float = 0.0) -> Bicycle:
    """loads (4,) static vertical loads rl rr fl fr (N); tires: 4 MagicFormula; yaw_inertia kg.m^2 at
    the centre of mass (for the frequency response only)."""
    c = [t.cornering_stiffness(float(f)) for t, f in zip(tires, loads, strict=True)]
    return Bicycle(wheelbase, (loads[2] + loads[3]) / g, (loads[0] + loads[1]) / g, c[2] + c[3], c[0] + c[1],
                   yaw_inertia)

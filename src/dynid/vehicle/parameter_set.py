"""A parameter set of the car template: named values with the source of each (a vehicle file's sections, the
paper's tables). A leaf: the vehicle file's reader (`vehicle.description`) and the sets of `vehicle.parameters`
both hold them."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class ParameterSet:
    """Named values (dynid names, e.g. K9) with the source of each value."""

    name: str
    values: dict[str, float]
    sources: dict[str, str] = field(default_factory=dict)

    def __getitem__(self, key: str) -> float:
        return self.values[key]

    def centre_of_mass(self, body: int = 6) -> tuple[float, float, float]:
        """(MX, MY, MZ) / M of a body, m, in its frame."""
        v = self.values
        M = v[f"M{body}"]
        return (v[f"MX{body}"] / M, v[f"MY{body}"] / M, v[f"MZ{body}"] / M)

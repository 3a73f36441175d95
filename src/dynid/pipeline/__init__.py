"""The identification pipeline: measurements -> conditioned trajectories -> (W, Y) -> estimates -> validation."""

from .reference import Match, ReferenceRow, match_reference, parse_combination, read_reference
from .robot import Conditioning, GroupedSystem, JointTest, condition, joint_system

__all__ = [
    "Conditioning", "GroupedSystem", "JointTest", "Match", "ReferenceRow", "condition", "joint_system",
    "match_reference", "parse_combination", "read_reference",
]

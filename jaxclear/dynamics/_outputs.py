"""Mapping access to a joint's per-instant outputs (``Trajectory.clearance[name]``), shared by the
revolute (``dynamics._clearance.ClearanceOutputs``) and translational
(``dynamics._translational.TranslationalClearanceOutputs``) clearance joints."""

import dataclasses
from typing import ClassVar

import equinox as eqx
from jaxtyping import Array


class JointOutputs(eqx.Module):
    """A module of output arrays read like a mapping: ``out["penetration"]``, ``out.keys()`` (the
    fields that are not ``None``, in field order), ``values``, ``items``, ``in``, ``len``, iteration.
    """

    kind: ClassVar[str] = "joint"
    """What the outputs belong to, for the message of an unknown key."""

    def keys(self) -> tuple[str, ...]:
        """Names of the outputs present (fields that are not ``None``), in field order."""
        return tuple(f.name for f in dataclasses.fields(self) if getattr(self, f.name) is not None)

    def values(self) -> tuple:
        return tuple(getattr(self, name) for name in self.keys())

    def items(self) -> tuple[tuple[str, Array], ...]:
        return tuple((name, getattr(self, name)) for name in self.keys())

    def __getitem__(self, key: str) -> Array:
        if key not in self.keys():
            raise KeyError(
                f"{key!r} is not an output of this {self.kind}; outputs: {', '.join(self.keys())}."
            )
        return getattr(self, key)

    def __contains__(self, key) -> bool:
        return key in self.keys()

    def __iter__(self):
        return iter(self.keys())

    def __len__(self) -> int:
        return len(self.keys())

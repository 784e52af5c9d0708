"""Registries of classes by kebab-case name (contact laws, friction laws), for configuration files
and the command line."""

from collections.abc import Iterator, Mapping
from typing import Any, Generic, TypeVar

T = TypeVar("T")


class Registry(Mapping[str, type[T]], Generic[T]):
    """Read-only mapping from registry name to class, with ``build(name, **params)``.

    Args:
        kind: what the entries are, for messages (e.g. ``"contact law"``).
        entries: name → class, in the order the names are listed in messages.
    """

    def __init__(self, kind: str, entries: Mapping[str, type[T]]):
        self._kind = kind
        self._entries = dict(entries)

    def __getitem__(self, name: str) -> type[T]:
        return self._entries[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self._kind!r}, {self._entries!r})"

    def build(self, name: str, **params: Any) -> T:
        """Instantiate ``self[name](**params)``.

        Raises:
            ValueError: ``name`` is not registered (the message lists the valid names), or a
                parameter is invalid (raised by the class).
        """
        try:
            cls = self._entries[name]
        except (KeyError, TypeError):
            valid = ", ".join(repr(k) for k in self._entries)
            raise ValueError(f"unknown {self._kind} {name!r}: use one of {valid}") from None
        return cls(**params)

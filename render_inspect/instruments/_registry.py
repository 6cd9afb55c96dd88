"""The registry of virtual instruments: each is one module of this package with its scene
schema class, found under ``[render.<name>]`` in a scene file (e.g.
``[render.interferometer]``)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["InstrumentType", "instrument_types", "register_instrument"]


@dataclass(frozen=True)
class InstrumentType:
    """A registered instrument: its ``[render.<name>]`` section name and schema class."""

    name: str
    config: type


_INSTRUMENTS: dict[str, InstrumentType] = {}


def register_instrument(name: str, config: type) -> InstrumentType:
    """Register an instrument whose settings are the scene section ``[render.<name>]``."""
    if not name.isidentifier():
        raise ValueError(f"instrument name must be an identifier, received {name!r}")
    entry = InstrumentType(name, config)
    _INSTRUMENTS[name] = entry
    return entry


def instrument_types() -> dict[str, InstrumentType]:
    """Section name -> :class:`InstrumentType`."""
    return dict(_INSTRUMENTS)

"""The registry of the servo families the lab drives: each family's folder
(:mod:`armlab.hardware.families`) adds its entry with :func:`register` when that package is
imported (``armlab.hardware`` imports it, so every family is here before anything asks),
and the bus, the scan, the joint map, the plant and the emulator ask :func:`family` (by
protocol, name or model) and call the family's methods instead of testing a protocol.
Nothing here names a family: the parts below the families find them through it.
"""

from __future__ import annotations

from armlab.hardware.servos.control_table import ControlTable
from armlab.hardware.servos.family import ServoFamily

#: Every family the lab drives, in the order a scan tries them (:func:`register` adds one:
#: :mod:`armlab.hardware.families` adds protocol 1.0, 2.0 and Feetech STS, in that order).
FAMILIES: list[ServoFamily] = []


def register(new: ServoFamily) -> None:
    """Add a family to :data:`FAMILIES` (what a family outside this package does once,
    before anything asks for it; its backends and emulator are named beside it by
    :func:`armlab.hardware.family_parts.register`).

    Raises:
        ValueError: its key, protocol tag, an alias or a model number is another family's.
    """
    for f in FAMILIES:
        names = {f.key, str(f.protocol), *f.aliases}
        clash = ({new.key, str(new.protocol), *new.aliases} & names
                 or set(new.tables) & set(f.tables))
        if clash:
            raise ValueError(f"the {new.title} family's {sorted(map(str, clash))} are the "
                             f"{f.title} family's")
    FAMILIES.append(new)


def family(which: int | float | str | ServoFamily) -> ServoFamily:
    """The family named by a protocol tag (1, 2.0, "sts"), a key or alias, or a family
    itself; ValueError listing the known ones otherwise."""
    if isinstance(which, ServoFamily):
        return which
    if isinstance(which, float) and which.is_integer():
        which = int(which)
    for f in FAMILIES:
        if which == f.protocol or (isinstance(which, str) and
                                   which.lower() in (f.key, str(f.protocol), *f.aliases)):
            return f
    raise ValueError(f"unknown servo family or protocol {which!r}; known: "
                     + ", ".join(f"{f.protocol!r} ({f.title})" for f in FAMILIES))


def family_of_model(model: int | str) -> ServoFamily:
    """The family one model (number or name) belongs to; ValueError listing every model."""
    for f in FAMILIES:
        if f.knows(model):
            return f
    tables = [t for f in FAMILIES for t in f.tables.values()]
    if isinstance(model, str):
        raise ValueError(f"unknown servo model {model!r}; known: "
                         f"{', '.join(t.name for t in tables)}")
    raise ValueError(f"unknown servo model number {model}; known: " + ", ".join(
        f"{t.spec.model_number} ({t.name})" for t in tables))


def family_of_spec(spec: object) -> ServoFamily:
    """The family of a datasheet object (a ``ServoSpec``, ``XSpec`` or ``StsSpec``): the
    one whose datasheet class it is, else the first it is a kind of (a family's datasheet
    may extend another's)."""
    for f in FAMILIES:
        if type(spec) is f.spec_type:
            return f
    for f in FAMILIES:
        if isinstance(spec, f.spec_type):
            return f
    raise ValueError(f"{spec!r} is no servo datasheet the lab knows")


def servo_table(model: int | str) -> ControlTable:
    """The control table of any model the lab knows (number or name)."""
    return family_of_model(model).table_for(model)

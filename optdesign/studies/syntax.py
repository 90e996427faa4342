"""The text syntax of pole regions and pole lists, shared by study specs (``region`` and
``poles`` in ``[fixed]``) and the command line (``optdesign design --region / --poles``).

Region syntax: members joined by ``&``, each ``shape:numbers`` -- ``halfplane:ALPHA`` (``Re s <=
-ALPHA``), ``sector:ZETA`` (damping ratio ``>= ZETA``), ``disk:RADIUS`` or ``disk:CENTER,RADIUS``,
``strip:LO,HI`` (``LO <= Re s <= HI``), ``hstrip:OMEGA`` (``|Im s| <= OMEGA``),
``ellipse:CENTER,A,B``, ``stable`` (``Re s <= 0``).  Example: ``"halfplane:1.5 & sector:0.7 &
disk:20"``.  Poles: ``"-1, -2, -3+1j, -3-1j"`` or a list of numbers / strings.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import OptDesignError, ValidationError
from ..model.regions import Disk, Ellipse, HalfPlane, HorizontalStrip, Region, Sector, VerticalStrip

__all__ = ["REGION_SHAPES", "parse_region", "format_region", "parse_poles"]


# --------------------------------------------------------------------------- region / pole syntax

#: shape -> (number of parameters accepted, constructor, help)
REGION_SHAPES: dict[str, tuple[tuple[int, ...], Any, str]] = {
    "halfplane": ((1,), lambda a: HalfPlane(a[0]), "halfplane:ALPHA  (Re s <= -ALPHA)"),
    "sector": ((1,), lambda a: Sector.from_damping(a[0]), "sector:ZETA  (damping ratio >= ZETA, 0 < ZETA < "
                                                          "1)"),
    "disk": ((1, 2), lambda a: Disk(0.0, a[0]) if len(a) == 1 else Disk(a[0], a[1]),
             "disk:RADIUS or disk:CENTER,RADIUS"),
    "strip": ((2,), lambda a: VerticalStrip(a[0], a[1]), "strip:LO,HI  (LO <= Re s <= HI)"),
    "hstrip": ((1,), lambda a: HorizontalStrip(a[0]), "hstrip:OMEGA  (|Im s| <= OMEGA)"),
    "ellipse": ((3,), lambda a: Ellipse(a[0], a[1], a[2]), "ellipse:CENTER,A,B"),
    "stable": ((0,), lambda a: HalfPlane(0.0), "stable  (Re s <= 0)"),
}


def parse_region(text: str, *, field: str = "region") -> Region:
    """Parse ``"halfplane:1.5 & sector:0.7 & disk:20"`` into a :class:`~optdesign.regions.Region`.

    Raises
    ------
    ValidationError
        One line starting with ``field``: unknown shape, wrong number of numbers, a value that is
        not a number, an invalid parameter (e.g. ``sector:1.2``) or an empty intersection.

    Examples
    --------
    >>> from optdesign.studies import parse_region
    >>> region = parse_region("halfplane:1.5 & sector:0.7 & disk:20")
    >>> [bool(region.contains([s])) for s in (-2.0, -1.0, -2.0 + 10.0j)]   # ok; slow; underdamped
    [True, False, False]
    """
    if not isinstance(text, str) or not text.strip():
        raise ValidationError(f"{field}: expected a region such as 'halfplane:1 & sector:0.7'; found "
                              f"{text!r}")
    members: list[Region] = []
    for term in text.split("&"):
        term = term.strip()
        if not term:
            raise ValidationError(f"{field}: empty member in {text!r} (members are joined by '&')")
        shape, _, args = term.partition(":")
        shape = shape.strip().lower()
        if shape not in REGION_SHAPES:
            raise ValidationError(f"{field}: unknown shape {shape!r} in {term!r}; expected one of "
                                  f"{', '.join(REGION_SHAPES)}")
        counts, make, usage = REGION_SHAPES[shape]
        parts = [a.strip() for a in args.split(",")] if args.strip() else []
        if len(parts) not in counts:
            raise ValidationError(f"{field}: {term!r} has {len(parts)} number(s); usage: {usage}")
        nums = []
        for a in parts:
            try:
                v = float(a)
            except ValueError:
                raise ValidationError(f"{field}: {a!r} in {term!r} is not a number; usage: {usage}") from None
            if not math.isfinite(v):
                raise ValidationError(f"{field}: {a!r} in {term!r} is not finite; usage: {usage}")
            nums.append(v)
        try:
            members.append(make(nums))
        except OptDesignError as exc:
            raise ValidationError(f"{field}: {term!r}: {exc}") from None
    region = members[0]
    try:
        for m in members[1:]:
            region = region & m
    except OptDesignError as exc:
        raise ValidationError(f"{field}: {' '.join(str(exc).split())}") from None
    return region


def _member_text(m: Region) -> tuple[str, str]:
    """(``--region`` syntax, meaning) of one region shape."""
    if isinstance(m, HalfPlane):
        if m.alpha == 0:
            return "stable", "Re s <= 0"
        return f"halfplane:{m.alpha:.6g}", f"Re s <= {-m.alpha:.6g}"
    if isinstance(m, Sector):
        deg = math.degrees(m.half_angle)
        if m.apex == 0:
            return (f"sector:{m.damping:.6g}",
                    f"damping ratio >= {m.damping:.6g} (a sector of half-angle {deg:.4g} deg)")
        return (f"Sector(half_angle={m.half_angle:.6g}, apex={m.apex:.6g})",
                f"|Im s| <= tan({deg:.4g} deg) ({m.apex:.6g} - Re s)")
    if isinstance(m, Disk):
        if m.center == 0:
            return f"disk:{m.radius:.6g}", f"|s| <= {m.radius:.6g}"
        return f"disk:{m.center:.6g},{m.radius:.6g}", f"|s - ({m.center:.6g})| <= {m.radius:.6g}"
    if isinstance(m, VerticalStrip):
        return f"strip:{m.lo:.6g},{m.hi:.6g}", f"{m.lo:.6g} <= Re s <= {m.hi:.6g}"
    if isinstance(m, HorizontalStrip):
        return f"hstrip:{m.omega:.6g}", f"|Im s| <= {m.omega:.6g}"
    if isinstance(m, Ellipse):
        return (f"ellipse:{m.center:.6g},{m.a:.6g},{m.b:.6g}",
                f"((Re s - ({m.center:.6g}))/{m.a:.6g})^2 + (Im s/{m.b:.6g})^2 <= 1")
    return repr(m), ""


def format_region(region: Region, *, meaning: bool = True) -> str:
    """A region in the syntax of :func:`parse_region` (its inverse), with what each member means.

    Examples
    --------
    >>> format_region(HalfPlane(1.0) & Disk(0.0, 20.0))
    'halfplane:1 & disk:20  (Re s <= -1; |s| <= 20)'
    >>> format_region(Sector.from_damping(0.7), meaning=False)
    'sector:0.7'
    """
    members = region.members if hasattr(region, "members") else (region,)
    parts = [_member_text(m) for m in members]
    text = " & ".join(p[0] for p in parts)
    glosses = [p[1] for p in parts if p[1]]
    return f"{text}  ({'; '.join(glosses)})" if meaning and glosses else text


def parse_poles(value: Any, *, field: str = "poles") -> np.ndarray:
    """Poles from ``"-1, -2, -3+1j, -3-1j"`` or a list of numbers / strings (complex vector).

    Raises
    ------
    ValidationError
        ``field`` named: an entry that is not a number, no entries.
    """
    items = [p.strip() for p in value.replace(";", ",").split(",")] if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not items:
        raise ValidationError(f"{field}: expected poles such as '-1, -2, -3+1j, -3-1j'; found {value!r}")
    out = []
    for s in items:
        try:
            z = complex(s.replace(" ", "").replace("i", "j")) if isinstance(s, str) else complex(s)
        except (ValueError, TypeError):
            raise ValidationError(f"{field}: {s!r} is not a number (write complex poles as -3+1j)") from None
        if not (math.isfinite(z.real) and math.isfinite(z.imag)):
            raise ValidationError(f"{field}: {s!r} is not finite")
        out.append(z)
    return np.asarray(out, dtype=complex)

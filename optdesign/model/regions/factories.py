"""Constructors of pole regions: the stability region of a time domain, and a region rebuilt from its
:meth:`~optdesign.model.regions.base.Region.to_dict` description.
"""

from __future__ import annotations

from typing import Any

from ..._validate import as_bool
from ...errors import ValidationError
from .base import Intersection, Region, real_param
from .shapes import Disk, Ellipse, HalfPlane, HorizontalStrip, Sector, VerticalStrip

__all__ = ["stability_region", "region_from_dict"]


# ----------------------------------------------------------------------------- factories
def stability_region(discrete: bool, margin: float = 0.0) -> Region:
    """The stability region of either time domain, shrunk by ``margin``.

    Parameters
    ----------
    discrete : bool
        ``False``: ``HalfPlane(margin)`` (``Re s <= -margin``); ``True``:
        ``Disk(0, 1 - margin)`` (``|z| <= 1 - margin``).
    margin : float, default 0.0
        Finite; for discrete time it must be ``< 1``.

    Raises
    ------
    ValidationError
        ``discrete`` not a bool; ``margin`` not a finite real number, or ``margin >= 1`` in discrete
        time.

    Examples
    --------
    >>> from optdesign.regions import stability_region
    >>> left = stability_region(discrete=False, margin=0.5)       # Re s <= -0.5
    >>> [bool(left.contains([s])) for s in (-1.0, -0.2)]
    [True, False]
    >>> disk = stability_region(discrete=True)                     # the unit disk
    >>> [bool(disk.contains([z])) for z in (0.5, 1.2)]
    [True, False]
    """
    discrete = as_bool("stability_region discrete", discrete)
    m = real_param("stability_region", "margin", margin)
    if discrete:
        if not m < 1.0:
            raise ValidationError(
                f"stability_region margin must be < 1 in discrete time (radius 1 - margin > 0); found {m!r}"
            )
        return Disk(0.0, 1.0 - m)
    return HalfPlane(m)


_TYPES: dict[str, type[Region]] = {
    c.__name__: c for c in (HalfPlane, Disk, Sector, VerticalStrip, HorizontalStrip, Ellipse)
}


def region_from_dict(d: dict[str, Any]) -> Region:
    """Rebuild a region from :meth:`Region.to_dict` output (e.g. read from a problem file).

    Raises
    ------
    ValidationError
        Not a mapping, unknown ``type``, or bad/missing parameters.

    Examples
    --------
    >>> from optdesign.regions import Disk, HalfPlane, region_from_dict
    >>> region = HalfPlane(1.0) & Disk(0.0, 10.0)
    >>> region_from_dict(region.to_dict()) == region
    True
    """
    if not isinstance(d, dict) or "type" not in d:
        raise ValidationError(f"a region description must be a dict with a 'type' key; found {d!r}")
    kind = d["type"]
    params = {k: v for k, v in d.items() if k != "type"}
    if kind == "Intersection":
        members = params.get("members")
        if not isinstance(members, (list, tuple)):
            raise ValidationError(f"an Intersection description needs a 'members' list; found {members!r}")
        return Intersection(*(region_from_dict(m) for m in members))
    if kind not in _TYPES:
        raise ValidationError(
            f"unknown region type {kind!r}; expected one of {sorted([*_TYPES, 'Intersection'])}"
        )
    try:
        return _TYPES[kind](**params)
    except TypeError as exc:
        raise ValidationError(f"bad parameters for region type {kind!r}: {exc}") from None

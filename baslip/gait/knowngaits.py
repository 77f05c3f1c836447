"""Gaits baslip ships, each at its normalised body: where a start from the body alone begins.

``known_gaits.json`` (beside this module) holds the verified gaits of the shipped
single-gait problems (``downward``, ``upward``, ``vpp``, ``vpp_human``), each carried to
the thesis-sized body with its groups (:mod:`baslip.model.similarity`). It is made from
their committed ``result.json`` files by :func:`known_gait_from_result`, and the tests
check that it still matches them and that every entry is a fixed point.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

from baslip.model.dynamics import Params
from baslip.model.quantities import posture_of
from baslip.model.similarity import Groups, body_with, carried, groups, normalised_body

#: The catalogue's file, shipped inside the package.
CATALOGUE = Path(__file__).with_name("known_gaits.json")


@dataclass(frozen=True)
class KnownGait:
    """A verified gait at its normalised body.

    Attributes
    ----------
    name : str
        The shipped problem it comes from.
    law : str
        Its hip law's name (``pd``, ``vpp``).
    groups : Groups
        Its body's dimensionless groups.
    values : Mapping of str to float
        Its design quantities at the normalised body (SI units, radians).
    """

    name: str
    law: str
    groups: Groups
    values: Mapping[str, float]

    @property
    def posture(self) -> str:
        """``upright`` (trunk above the hip at the apex) or ``hanging``."""
        return posture_of(self.values["theta_h"])

    @property
    def body(self) -> Params:
        """The normalised body it is a gait of."""
        return body_with(self.groups)


def known_gait_from_result(record: Mapping) -> KnownGait:
    """The catalogue entry of a verified gait's ``result.json`` record."""
    params = Params(**record["params"])
    values = {**record["apex"], **record["control"]}
    return KnownGait(record["name"], record["hip_law"], groups(params),
                     MappingProxyType(carried(values, params, normalised_body(params))))


def known_gaits() -> tuple[KnownGait, ...]:
    """Every gait of the catalogue."""
    entries = json.loads(CATALOGUE.read_text())
    return tuple(KnownGait(e["name"], e["law"], Groups(**e["groups"]), MappingProxyType(e["values"])) for e in entries)


def catalogue_text(gaits: tuple[KnownGait, ...]) -> str:
    """``gaits`` as the catalogue file's JSON."""
    entries = [{"name": g.name, "law": g.law, "groups": dict(zip(("stiffness", "inertia", "offset"), g.groups.values())),
                "values": dict(g.values)} for g in gaits]
    return json.dumps(entries, indent=1) + "\n"

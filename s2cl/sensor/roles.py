"""Band roles by wavelength: which of a sensor's bands plays each band an application names.

An application names its bands as the scene's sensor does (Sentinel-2's ``B4 B5 B6 B8``, say); each is a *role*
at that band's centre (665, 705, 740, 842 nm). On another sensor each role is played by the sensor's band whose
centre is nearest the role's, within a tolerance (:data:`DEFAULT_TOLERANCE_NM`, inclusive; on a tie the band
listed first). A sensor whose bands are named as the scene's (Sentinel-2A/2B, a sweep's design) maps each role to
its band of that name instead. A role no band plays, or two roles one band would play, leaves the sensor without
the application: "n/a" with the reason, never an error. :func:`map_roles` is the one rule the scorecard
(:mod:`s2cl.app.scorecard`) and its documentation use.
"""

from __future__ import annotations

from dataclasses import dataclass

from s2cl.sensor.sensor import Sensor

#: how far (nm) a sensor band's centre may lie from a role's centre and still play it
DEFAULT_TOLERANCE_NM = 15.0


@dataclass(frozen=True)
class RoleMatch:
    """Role ``role`` (centre ``wavelength_nm``) played by ``band`` of the sensor, or by none (``band`` None)."""

    role: str
    wavelength_nm: float
    band: str | None


@dataclass(frozen=True)
class RoleMapping:
    """The roles of one application on one sensor: ``matches`` in the roles' order, and ``missing``: why the sensor
    cannot run the application (None when every role has a band of its own)."""

    matches: tuple[RoleMatch, ...]
    missing: str | None

    @property
    def bands(self) -> dict[str, str]:
        """Role → the sensor band that plays it (the matched roles only)."""
        return {m.role: m.band for m in self.matches if m.band is not None}


def nearest_band(sensor: Sensor, wavelength_nm: float, tolerance_nm: float = DEFAULT_TOLERANCE_NM) -> str | None:
    """The name of ``sensor``'s band whose centre is nearest ``wavelength_nm`` and at most ``tolerance_nm`` away
    (the first listed on a tie), or None."""
    best, gap = None, float("inf")
    for band in sensor.bands:
        d = abs(band.centre_nm - wavelength_nm)
        if d < gap:
            best, gap = band.name, d
    return best if gap <= tolerance_nm + 1e-9 else None


def map_roles(roles: dict[str, float], sensor: Sensor, tolerance_nm: float = DEFAULT_TOLERANCE_NM, *,
              by_name: bool = False) -> RoleMapping:
    """Each role of ``roles`` (name → centre, nm) on ``sensor``: its band of the role's name when ``by_name`` (and
    it has one), else its band nearest the role's centre within ``tolerance_nm`` (:func:`nearest_band`). ``missing``
    names the first role without a band (``no band near 783 nm``) or two roles on one band."""
    names = {n.lower(): n for n in sensor.band_names}
    matches = []
    for role, wl in roles.items():
        band = names.get(role.lower()) if by_name else None
        matches.append(RoleMatch(role, float(wl), band or nearest_band(sensor, wl, tolerance_nm)))
    missing = None
    lost = [m for m in matches if m.band is None]
    if lost:
        missing = f"no band near {lost[0].wavelength_nm:g} nm ({lost[0].role}, within {tolerance_nm:g} nm)"
    else:
        seen: dict[str, str] = {}
        for m in matches:
            assert m.band is not None
            if m.band in seen:
                missing = (f"{seen[m.band]} and {m.role} would both be band {m.band} "
                           f"({sensor.band(m.band).centre_nm:g} nm)")
                break
            seen[m.band] = m.role
    return RoleMapping(tuple(matches), missing)

"""Which side of the road traffic keeps to, from where an OSM extract lies.

OSM extracts rarely say it (``driving_side`` belongs on the country's boundary relation, which an extract
does not hold; wiki.openstreetmap.org/wiki/Key:driving_side), and netconvert builds right-hand traffic
unless told ``--lefthand``. ``scenario.driving_side: auto`` looks up the country at the centre of the
extract's nodes: its time zone (timezonefinder, on the timezone-boundary-builder polygons drawn from OSM's
own boundaries) and the zone's country (the tz database's zone.tab); ``left`` or ``right`` overrides it.
"""

from __future__ import annotations

from functools import cache
from importlib import resources

# ISO 3166-1 alpha-2 codes of the countries and territories that drive on the left (en.wikipedia.org/wiki/
# Left-_and_right-hand_traffic, "Countries and territories with left-hand traffic", as of 2025; Samoa
# since 2009; Gibraltar, unlike the UK, drives on the right)
LEFT_HAND_COUNTRIES = frozenset(
    # Europe
    "GB IE IM JE GG CY MT "
    # Asia
    "JP IN PK BD LK NP BT MV TH MY SG BN ID TL HK MO "
    # Oceania
    "AU NZ PG FJ SB TO WS KI TV NR NU CK NF CX CC PN TK "
    # Africa and the Indian Ocean
    "ZA NA BW LS SZ ZW ZM MW MZ TZ KE UG MU SC SH IO "
    # the Americas and the Caribbean
    "JM BS BB TT GY SR AG DM GD KN LC VC AI BM KY MS TC VG VI FK".split()
)

SETTINGS = ("auto", "right", "left")


@cache
def _zone_countries() -> dict[str, str]:
    """Time zone -> ISO country code, from the tz database's zone.tab (the tzdata package)."""
    text = resources.files("tzdata").joinpath("zoneinfo", "zone.tab").read_text(encoding="utf-8")
    out = {}
    for line in text.splitlines():
        if line and not line.startswith("#"):
            cc, _, zone, *_ = line.split("\t")
            out[zone] = cc
    return out


@cache
def _finder():
    from timezonefinder import TimezoneFinder

    return TimezoneFinder()


def lookup_version() -> str:
    """The versions of the data ``auto`` decides by (part of a built network's cache key)."""
    from importlib.metadata import PackageNotFoundError, version

    found = []
    for pkg in ("timezonefinder", "timezonefinder_data", "tzdata"):  # the data package: timezonefinder >= 7
        try:
            found.append(f"{pkg} {version(pkg)}")
        except PackageNotFoundError:
            pass
    return ", ".join(found)


def country_at(lat: float, lon: float) -> tuple[str | None, str | None]:
    """(time zone, ISO country code) at a place; None where the map has no country (the open sea)."""
    zone = _finder().timezone_at(lng=lon, lat=lat)
    return zone, _zone_countries().get(zone) if zone else None


def resolve(setting: str, centre: tuple[float, float] | None) -> tuple[bool, str]:
    """(whether traffic keeps to the left, how that was decided) for ``scenario.driving_side`` ``setting``
    and the (lat, lon) centre of the extract's nodes."""
    if setting not in SETTINGS:
        raise ValueError(f"driving_side must be one of {', '.join(SETTINGS)}, got {setting!r}")
    if setting != "auto":
        return setting == "left", f"{setting} (scenario.driving_side)"
    if centre is None:
        return (
            False,
            "right (the extract has no nodes to place it; set scenario.driving_side if that is wrong)",
        )
    lat, lon = centre
    zone, country = country_at(lat, lon)
    if country is None:
        return False, (
            f"right (no country at {lat:.4f}, {lon:.4f}, the extract's centre; set scenario.driving_side if that "
            "is wrong)"
        )
    left = country in LEFT_HAND_COUNTRIES
    return left, f"{'left' if left else 'right'} ({country}: time zone {zone} at the extract's centre)"

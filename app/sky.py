"""The sun's place in the model, from the date, the time and the site (``sky.*`` settings).

The solar position is astral's (a maintained implementation of the NOAA algorithm), not a
formula written here. ``sky.time`` is local mean solar time: the clock of the site's meridian,
UTC plus the longitude over 15 degrees per hour, so no time zone setting is needed and noon is
always near the sun's highest point. Directions follow the scene's axes: Y up, and north along
the model's -Z turned counter-clockwise (seen from above) by ``sky.north_deg``.
"""

from __future__ import annotations

import datetime
import math
from dataclasses import dataclass

import numpy as np
from astral import Observer
from astral.sun import azimuth, elevation

from app.settings import SkySettings


@dataclass(frozen=True)
class SunPosition:
    azimuth_deg: float  # clockwise from north, seen from above (east 90)
    elevation_deg: float  # above the horizon; negative: below it (night)


def utc_moment(sky: SkySettings) -> datetime.datetime:
    """The UTC moment of ``sky.date`` ``sky.time`` in the site's local mean solar time."""
    day = datetime.date.fromisoformat(sky.date)
    hours, minutes = (int(part) for part in sky.time.split(":"))
    local = datetime.datetime(
        day.year, day.month, day.day, hours, minutes, tzinfo=datetime.timezone.utc
    )
    return local - datetime.timedelta(hours=sky.longitude / 15.0)


def sun_position(sky: SkySettings) -> SunPosition:
    """The sun's azimuth and elevation (degrees, refraction included) for the settings."""
    where = Observer(latitude=sky.latitude, longitude=sky.longitude)
    when = utc_moment(sky)
    return SunPosition(float(azimuth(where, when)), float(elevation(where, when)))


def north_east(north_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of north and east in scene axes for ``sky.north_deg``."""
    t = math.radians(north_deg)
    north = np.array([-math.sin(t), 0.0, -math.cos(t)])
    east = np.array([math.cos(t), 0.0, -math.sin(t)])
    return north, east


def sun_direction(sky: SkySettings) -> np.ndarray:
    """Unit vector from the room towards the sun, in scene axes (y < 0: below the horizon)."""
    pos = sun_position(sky)
    north, east = north_east(sky.north_deg)
    az, el = math.radians(pos.azimuth_deg), math.radians(pos.elevation_deg)
    horizontal = north * math.cos(az) + east * math.sin(az)
    return horizontal * math.cos(el) + np.array([0.0, math.sin(el), 0.0])

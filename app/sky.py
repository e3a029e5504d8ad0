"""The sun's place in the model, from the date, the time and the site (``sky.*`` settings).

The solar position is astral's (a maintained implementation of the NOAA algorithm), not a
formula written here. ``sky.time`` is local mean solar time: the clock of the site's meridian,
UTC plus the longitude over 15 degrees per hour, so no time zone setting is needed and noon is
always near the sun's highest point. Directions follow the scene's axes: Y up, and north along
the model's -Z turned counter-clockwise (seen from above) by ``sky.north_deg``.
"""

from __future__ import annotations

import dataclasses
import datetime
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from astral import Observer
from astral.sun import azimuth, elevation

from app.scene import Light
from app.settings import Settings, SkySettings
from app.sky_model import (
    GROUND_REFLECTANCE,
    LUMA,
    equirect_directions,
    irradiance_sh,
    sky_radiance,
    sun_light_of,
)

log = logging.getLogger(__name__)


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


def _sky_of(settings: SkySettings | Settings) -> SkySettings:
    return settings.sky if isinstance(settings, Settings) else settings


def sun_light(settings: SkySettings | Settings) -> Light | None:
    """The sun as a directional light (illuminance in lux, colour of unit luminance), or None
    below the horizon. ``direction`` is the way its light travels: away from the sun."""
    sky = _sky_of(settings)
    pos = sun_position(sky)
    light = sun_light_of(pos.elevation_deg)
    if light is None:
        return None
    travel = -sun_direction(sky)
    return Light(
        position=(0.0, 0.0, 0.0),
        color=light.color,
        intensity=light.illuminance_lux,
        range_m=math.inf,
        kind="directional",
        direction=(float(travel[0]), float(travel[1]), float(travel[2])),
        casts_shadows=True,
    )


def sky_key(sky: SkySettings) -> tuple:
    """What the sky depends on, hashable: time, date, latitude, longitude, north, photo."""
    return (sky.time, sky.date, sky.latitude, sky.longitude, sky.north_deg, sky.image)


def sky_of_key(key: tuple) -> SkySettings:
    """The daylit settings of a :func:`sky_key`."""
    time, date, lat, lon, north, image = key
    return SkySettings(
        enabled=True,
        time=time,
        date=date,
        latitude=lat,
        longitude=lon,
        north_deg=north,
        image=image,
    )


@dataclass
class SkyBake:
    """The sky for one set of ``sky.*`` settings, baked on the CPU (not per frame)."""

    image: np.ndarray  # (H, W, 3) float32 linear RGB radiance in cd/m2, equirectangular
    sh: np.ndarray  # (9, 3) diffuse light of a white surface per unit normal (sky_model.sh)
    sun: Light | None
    warning: str | None = None  # why the sky photo was not used, in words
    from_image: bool = False
    outdoor_lux: float = 0.0  # horizontal illuminance in the open from the sun and the sky


SKY_SIZE = (128, 64)  # equirectangular texels: the diffuse light needs no more


def bake_sky(settings: SkySettings | Settings, size: tuple[int, int] = SKY_SIZE) -> SkyBake:
    """The computed (Preetham) sky with a ground below the horizon, or the user's panorama
    (``sky.image``) scaled to the computed sky's brightness for that date and time; a file
    that cannot be read gives the computed sky and a warning."""
    sky = _sky_of(settings)
    width, height = size
    north, east = north_east(sky.north_deg)
    dirs, solid = equirect_directions(width, height, north, east)
    to_sun = sun_direction(sky)
    sun = sun_light(sky)
    flat = dirs.reshape(-1, 3)
    rgb = sky_radiance(flat, to_sun).reshape(height, width, 3)
    upper = dirs[..., 1] > 0.0
    # Horizontal illuminance from the sky dome and the sun, for the ground's brightness.
    e_sky = (rgb * (solid * np.maximum(dirs[..., 1], 0.0))[..., None]).sum(axis=(0, 1))
    e_sun = np.zeros(3)
    if sun is not None:
        e_sun = np.asarray(sun.color) * sun.intensity * max(float(to_sun[1]), 0.0)
    outdoor_lux = float((e_sky + e_sun) @ LUMA)
    ground = GROUND_REFLECTANCE * (e_sky + e_sun) / math.pi * np.array([1.0, 0.95, 0.85])
    rgb = np.where(upper[..., None], rgb, ground[None, None, :])
    warning = None
    from_image = False
    if sky.image:
        try:
            photo = read_panorama(sky.image, size)
        except (OSError, ValueError) as exc:
            warning = (
                f"The sky photo {sky.image} could not be used ({exc}); showing the computed sky."
            )
            log.warning("%s", warning)
        else:
            # A photo's pixel values have no unit: scale its dome to the computed dome's mean.
            w_up = solid * upper
            want = float((rgb @ LUMA * w_up).sum())
            have = float((photo @ LUMA * w_up).sum())
            rgb = photo * (want / have if have > 1e-9 else 1.0)
            from_image = True
    rgb = rgb.astype(np.float32)
    return SkyBake(rgb, irradiance_sh(rgb, dirs, solid), sun, warning, from_image, outdoor_lux)


def unlit_gain(bake: SkyBake | None) -> float:
    """How many times brighter than their 1-lux glow (``app.gltf_materials.UNLIT_CD_M2``)
    unlit materials show: with daylight on (``bake``), the day's outdoor horizontal illuminance
    in lux, so that a white pixel of a photo backdrop outside the window is as bright as a
    white card in the open and its sky about as bright as the sky (at 1 lux it was a black pane
    beside a sky of thousands of cd/m2); at night, or with daylight off, 1."""
    return 1.0 if bake is None else max(bake.outdoor_lux, 1.0)


def read_panorama(path: str, size: tuple[int, int] = SKY_SIZE) -> np.ndarray:
    """An equirectangular photo as linear RGB (H, W, 3) float, resampled to ``size``: HDR and
    EXR files as stored (linear), JPG and PNG decoded from sRGB. Raises OSError or ValueError."""
    from PIL import Image

    suffix = Path(path).suffix.lower()
    if not Path(path).is_file():
        raise OSError("no such file")
    linear = suffix in (".hdr", ".exr")
    try:
        if suffix == ".hdr":
            data = read_radiance_hdr(path)
        elif suffix == ".exr":
            data = read_exr(path)
        else:
            with Image.open(path) as im:
                data = np.asarray(im.convert("RGB"), np.float32) / 255.0
    except (OSError, ValueError):
        raise
    except Exception as exc:  # noqa: BLE001 - the decoders raise many kinds for a bad file
        raise ValueError(f"not a readable image: {exc}") from exc
    if data.ndim == 2:
        data = np.repeat(data[..., None], 3, axis=2)
    data = data[..., :3]
    if data.shape[0] < 2 or data.shape[1] < 2 or not np.isfinite(data).all():
        raise ValueError("the image is empty or holds invalid values")
    if not linear:
        data = np.where(data <= 0.04045, data / 12.92, ((data + 0.055) / 1.055) ** 2.4)
    # Box-filter down (a sky this small only feeds the diffuse light and a soft background).
    width, height = size
    rows = np.linspace(0, data.shape[0], height + 1).astype(int)
    cols = np.linspace(0, data.shape[1], width + 1).astype(int)
    rows[1:] = np.maximum(rows[1:], rows[:-1] + 1)
    cols[1:] = np.maximum(cols[1:], cols[:-1] + 1)
    rows, cols = np.minimum(rows, data.shape[0]), np.minimum(cols, data.shape[1])
    row_sums = np.add.reduceat(data, rows[:-1], axis=0)
    sums = np.add.reduceat(row_sums, cols[:-1], axis=1)
    counts = np.diff(rows)[:, None, None] * np.diff(cols)[None, :, None]
    return np.maximum(sums / np.maximum(counts, 1), 0.0)


def read_exr(path: str) -> np.ndarray:
    """An OpenEXR image's RGB channels as float32 (H, W, 3), through the OpenEXR package."""
    import OpenEXR

    with OpenEXR.File(path) as f:
        channels = f.channels()
        if "RGB" in channels:
            return np.asarray(channels["RGB"].pixels, np.float32)
        if "RGBA" in channels:
            return np.asarray(channels["RGBA"].pixels, np.float32)[..., :3]
        names = [n for n in ("R", "G", "B") if n in channels]
        if not names:
            raise ValueError("the EXR file has no colour channels")
        return np.stack([np.asarray(channels[n].pixels, np.float32) for n in names], -1)


def read_radiance_hdr(path: str) -> np.ndarray:
    """A Radiance RGBE picture (.hdr, G. Ward, "Real Pixels", Graphics Gems II, 1991) as
    float32 (H, W, 3): flat or run-length encoded scanlines, the usual -Y H +X W orientation."""
    raw = Path(path).read_bytes()
    if not raw.startswith((b"#?RADIANCE", b"#?RGBE")):
        raise ValueError("not a Radiance HDR file")
    end = raw.find(b"\n\n")
    if end < 0:
        raise ValueError("the HDR header does not end")
    if b"FORMAT=32-bit_rle_xyze" in raw[:end]:
        raise ValueError("XYZE HDR files are not supported")
    line_end = raw.find(b"\n", end + 2)
    size = raw[end + 2 : line_end].split()
    if len(size) != 4 or size[0] != b"-Y" or size[2] != b"+X":
        raise ValueError("unsupported HDR orientation")
    height, width = int(size[1]), int(size[3])
    data = np.frombuffer(raw, np.uint8, offset=line_end + 1)
    rgbe = np.empty((height, width, 4), np.uint8)
    pos = 0
    for y in range(height):
        head = data[pos : pos + 4]
        rle = 8 <= width < 32768 and len(head) == 4 and head[0] == 2 and head[1] == 2
        if not rle or (int(head[2]) << 8 | int(head[3])) != width:
            count = width * 4
            if pos + count > data.size:
                raise ValueError("the HDR file is cut short")
            rgbe[y] = data[pos : pos + count].reshape(width, 4)
            pos += count
            continue
        pos += 4
        for c in range(4):
            x = 0
            while x < width:
                if pos >= data.size:
                    raise ValueError("the HDR file is cut short")
                n = int(data[pos])
                pos += 1
                if n > 128:  # a run
                    n -= 128
                    if x + n > width or pos >= data.size:
                        raise ValueError("bad HDR run length")
                    rgbe[y, x : x + n, c] = data[pos]
                    pos += 1
                else:
                    if n == 0 or x + n > width or pos + n > data.size:
                        raise ValueError("bad HDR run length")
                    rgbe[y, x : x + n, c] = data[pos : pos + n]
                    pos += n
                x += n
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0).astype(np.float32)
    return rgbe[..., :3].astype(np.float32) * scale[..., None]


def scene_sky(sky: SkySettings, scene: object) -> SkySettings:
    """The sky settings as they apply to ``scene``: a scene that knows its north
    (``Scene.north_deg``, the showroom's) is turned by it, and ``sky.north_deg`` turns it
    further; a model file that says nothing has north along -Z turned by the setting alone."""
    own = getattr(scene, "north_deg", None)
    if own is None or not math.isfinite(float(own)) or float(own) == 0.0:
        return sky
    return dataclasses.replace(sky, north_deg=float(own) + float(sky.north_deg))

"""The clear sky in physical units: the sun's illuminance and colour, the sky's luminance.

No maintained Python package computes an analytic sky dome (pvlib's clear-sky models give
irradiance sums, not the sky's radiance per direction, and would bring pandas), so the
formulas are written here, each from its paper:

- Sky luminance and colour: A. J. Preetham, P. Shirley, B. Smits, "A Practical Analytic Model
  for Daylight", SIGGRAPH 1999, appendix A.2 (Perez distribution coefficients, zenith
  luminance in kcd/m2 and zenith chromaticity as functions of turbidity and sun angle).
- The sun's direct normal irradiance: A. B. Meinel, M. P. Meinel, "Applied Solar Energy"
  (1976): DNI = 1353 W/m2 * 0.7 ** (m ** 0.678), with the air mass m of F. Kasten,
  A. T. Young, "Revised optical air mass tables", Applied Optics 28 (1989); converted to lux
  with a direct-beam luminous efficacy of 93 lm/W (P. R. Littlefair, "The luminous efficacy
  of daylight: a review", Lighting Res. Technol. 17 (1985), clear-sky beam 90-105 lm/W).
- The sun's colour: its transmittance through Rayleigh scattering (Leckner 1978,
  0.008735 * lambda ** -4.08) and haze (Angstrom, beta = 0.04608 T - 0.04586, Preetham's
  appendix A.1) at 650, 550 and 450 nm, normalised to unit luminance.

Below the horizon the sun gives no light; the sky fades through twilight (a tenfold drop every
3 degrees of the sun below the horizon) to a night floor. The ground below the horizon is a
grey of 20 % reflectance lit by the sun and sky. Colours are linear Rec. 709 / sRGB
primaries, luminance in cd/m2 (the renderer's unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TURBIDITY = 3.0  # a clear day (Preetham: 2 very clear, 6 hazy)
SOLAR_DNI_W = 1353.0  # W/m2 outside the atmosphere (Meinel's constant)
BEAM_EFFICACY_LM_W = 93.0  # lm/W, clear-sky direct beam (Littlefair 1985)
GROUND_REFLECTANCE = 0.2
NIGHT_LUMINANCE = 0.002  # cd/m2: a moonless night sky
SUN_HALF_ANGLE_DEG = 0.266
_XYZ_TO_RGB = np.array(
    [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]]
)
LUMA = np.array([0.2126, 0.7152, 0.0722])


def air_mass(elevation_deg: float) -> float:
    """Kasten-Young relative optical air mass (1 at the zenith, about 38 at the horizon)."""
    z = 90.0 - max(elevation_deg, 0.0)
    return 1.0 / (math.cos(math.radians(z)) + 0.50572 * (96.07995 - z) ** -1.6364)


@dataclass(frozen=True)
class SunLight:
    illuminance_lux: float  # on a surface facing the sun
    color: tuple[float, float, float]  # linear RGB of unit luminance


def sun_light_of(elevation_deg: float, turbidity: float = TURBIDITY) -> SunLight | None:
    """The sun's direct light for its elevation (None at or below the horizon)."""
    if elevation_deg <= 0.0:
        return None
    m = air_mass(elevation_deg)
    dni = SOLAR_DNI_W * 0.7 ** (m**0.678)
    lam = np.array([0.65, 0.55, 0.45])  # micrometres: red, green, blue
    beta = 0.04608 * turbidity - 0.04586
    tau = 0.008735 * lam**-4.08 + beta * lam**-1.3
    rgb = np.exp(-m * tau)
    rgb = rgb / float(LUMA @ rgb)
    return SunLight(float(dni * BEAM_EFFICACY_LM_W), (float(rgb[0]), float(rgb[1]), float(rgb[2])))


def _perez(theta: np.ndarray, gamma: np.ndarray, c: tuple[float, ...]) -> np.ndarray:
    a, b, cc, d, e = c
    cos_t = np.maximum(np.cos(theta), 0.01)
    return (1.0 + a * np.exp(b / cos_t)) * (1.0 + cc * np.exp(d * gamma) + e * np.cos(gamma) ** 2)


def _coefficients(t: float) -> tuple[tuple[float, ...], ...]:
    """Preetham's appendix A.2: Perez coefficients of luminance Y and chromaticity x, y."""
    y_c = (0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251,
           0.1206 * t - 2.5771, -0.0670 * t + 0.3703)  # fmt: skip
    x_c = (-0.0193 * t - 0.2592, -0.0665 * t + 0.0008, -0.0004 * t + 0.2125,
           -0.0641 * t - 0.8989, -0.0033 * t + 0.0452)  # fmt: skip
    yy_c = (-0.0167 * t - 0.2608, -0.0950 * t + 0.0092, -0.0079 * t + 0.2102,
            -0.0441 * t - 1.6537, -0.0109 * t + 0.0529)  # fmt: skip
    return y_c, x_c, yy_c


def _zenith(t: float, theta_s: float) -> tuple[float, float, float]:
    """Zenith luminance (cd/m2) and chromaticity x, y (Preetham A.2)."""
    chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * theta_s)
    lum = ((4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192) * 1000.0
    s3, s2, s1 = theta_s**3, theta_s**2, theta_s
    x = (
        t * t * (0.00166 * s3 - 0.00375 * s2 + 0.00209 * s1)
        + t * (-0.02903 * s3 + 0.06377 * s2 - 0.03202 * s1 + 0.00394)
        + (0.11693 * s3 - 0.21196 * s2 + 0.06052 * s1 + 0.25886)
    )
    y = (
        t * t * (0.00275 * s3 - 0.00610 * s2 + 0.00317 * s1)
        + t * (-0.04214 * s3 + 0.08970 * s2 - 0.04153 * s1 + 0.00516)
        + (0.15346 * s3 - 0.26756 * s2 + 0.06670 * s1 + 0.26688)
    )
    return max(lum, 0.0), x, y


def sky_radiance(
    directions: np.ndarray, to_sun: np.ndarray, turbidity: float = TURBIDITY
) -> np.ndarray:
    """Sky luminance as linear RGB (cd/m2) for unit ``directions`` (N, 3), Y up, with the sun
    towards ``to_sun``; directions below the horizon get the sky's value at the horizon (the
    caller paints the ground)."""
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    s = np.asarray(to_sun, np.float64)
    s = s / max(float(np.linalg.norm(s)), 1e-12)
    sun_el = math.degrees(math.asin(max(-1.0, min(1.0, float(s[1])))))
    # Preetham holds for the sun above the horizon: below it, the horizon sun's sky, dimmed.
    flat = np.array([s[0], 0.0, s[2]])
    if sun_el < 1.0:
        h = flat / max(float(np.linalg.norm(flat)), 1e-9)
        s = h * math.cos(math.radians(1.0)) + np.array([0.0, math.sin(math.radians(1.0)), 0.0])
    theta_s = math.acos(max(-1.0, min(1.0, float(s[1]))))
    up = np.clip(d[:, 1], 0.0, 1.0)
    theta = np.arccos(up)
    gamma = np.arccos(np.clip(d @ s, -1.0, 1.0))
    y_c, x_c, yy_c = _coefficients(turbidity)
    lum_z, x_z, y_z = _zenith(turbidity, theta_s)
    ts, zero = np.array([theta_s]), np.array([0.0])
    lum = lum_z * _perez(theta, gamma, y_c) / _perez(zero, ts, y_c)
    x = x_z * _perez(theta, gamma, x_c) / _perez(zero, ts, x_c)
    y = y_z * _perez(theta, gamma, yy_c) / _perez(zero, ts, yy_c)
    y = np.maximum(y, 1e-4)
    xyz = np.stack([x * lum / y, lum, (1.0 - x - y) * lum / y], axis=1)
    rgb = np.maximum(xyz @ _XYZ_TO_RGB.T, 0.0)
    if sun_el < 1.0:
        rgb *= 10.0 ** (min(sun_el - 1.0, 0.0) / 3.0)  # twilight: tenfold per 3 degrees
    night = NIGHT_LUMINANCE * np.array([0.5, 0.7, 1.4])
    return rgb + night


def equirect_directions(width: int, height: int, north: np.ndarray, east: np.ndarray):
    """Unit direction (H, W, 3) and solid angle (H, W) of each texel of an equirectangular
    map in scene axes: row 0 the zenith, the middle column facing north, east to its right
    (the way a panorama photo is laid out when its middle looks north)."""
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    theta = v * math.pi  # from the zenith
    phi = (u - 0.5) * 2.0 * math.pi  # compass azimuth: 0 north, +90 east
    st, ct = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    horiz = (
        np.cos(phi)[None, :, None] * np.asarray(north)[None, None, :]
        + np.sin(phi)[None, :, None] * np.asarray(east)[None, None, :]
    )
    d = horiz * st + ct * np.array([0.0, 1.0, 0.0])[None, None, :]
    solid = (2.0 * math.pi / width) * (math.pi / height) * np.sin(theta)[:, None]
    return d, np.broadcast_to(solid, (height, width))


def irradiance_sh(radiance: np.ndarray, dirs: np.ndarray, solid: np.ndarray) -> np.ndarray:
    """Nine spherical-harmonic coefficients (9, 3) of the diffuse light leaving a white
    surface, L_out(n) = E(n) / pi (R. Ramamoorthi, P. Hanrahan, "An Efficient Representation
    for Irradiance Environment Maps", SIGGRAPH 2001, eq. 7-8, the 1/pi folded in)."""
    d = dirs.reshape(-1, 3)
    w = solid.reshape(-1, 1) * radiance.reshape(-1, 3)
    basis = sh_basis(d)
    coeffs = basis.T @ w  # (9, 3): L_lm
    a = np.array([math.pi] + [2.0 * math.pi / 3.0] * 3 + [math.pi / 4.0] * 5)
    return coeffs * (a / math.pi)[:, None]


def sh_basis(d: np.ndarray) -> np.ndarray:
    """Real spherical harmonics up to l = 2 for unit directions (N, 3) (the same order and
    constants as render/shaders/sky.glsl's sky_sh)."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack(
        [
            np.full_like(x, 0.282095),
            0.488603 * y,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * y,
            1.092548 * y * z,
            0.315392 * (3.0 * z * z - 1.0),
            1.092548 * x * z,
            0.546274 * (x * x - y * y),
        ],
        axis=1,
    )

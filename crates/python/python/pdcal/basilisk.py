"""Build a pdcal ``Dataset`` from Basilisk recorder output.

Pure Python over numpy: Basilisk is not imported here, so the arrays may come from a live
simulation (``msg.recorder()``), from saved ``.npz`` files or from any other tool that uses
Basilisk's conventions. The conversions are written down in ``docs/basilisk.md``; in short:

* Basilisk's inertial frame N is taken as GCRF (pdcal's inertial frame). Basilisk's Sun and
  Earth states come from SPICE (J2000) or from messages the user writes; either way N is the
  frame they are expressed in, and J2000 and GCRF differ by the 0.02 arcsec frame bias.
* ``sigma_BN`` (MRP) gives ``[BN]`` with ``v_B = [BN] v_N``; pdcal's quaternion (scalar last)
  has ``A(q) = [BN]``, so ``q = (beta_1, beta_2, beta_3, beta_0)`` of the Euler parameters.
* ``r_BN_N`` is in metres; pdcal wants km.
* ``IMUSensorMsg.AngVelPlatform`` is in rad/s in the IMU platform frame P:
  ``omega_B = [PB]^T omega_P``.
* ``TAMSensorMsg.tam_S`` is in tesla in the sensor frame S: ``B_B = [SB]^T tam_S * 1e9`` nT.
* ``CSSArraySensorMsg.CosValue`` (or each ``CSSRawDataMsg.OutputData``) is already multiplied by
  the sensor's ``scaleFactor``: with ``scaleFactor`` in volts it is pdcal's ``pdNN_V``, and the
  ``scaleFactor`` is pdcal's scale ``C`` (output at 1 AU, normal incidence).
* A CSS normal ``nHat_B`` is pdcal's ``n = [cos(el) cos(az), cos(el) sin(az), sin(el)]``, the
  same as Basilisk's ``theta`` (azimuth) and ``phi`` (elevation) when ``dcm_PB`` is identity.
"""

from __future__ import annotations

import datetime as _dt
from typing import Any, Mapping, Optional, Sequence

import numpy as np

__all__ = [
    "mrp_to_quaternion",
    "quaternion_to_dcm",
    "normal_to_az_el_deg",
    "az_el_deg_to_normal",
    "epoch_utc_string",
    "common_time_line",
    "dataset_kwargs_from_basilisk",
    "dataset_from_basilisk",
    "truth_from_basilisk",
    "NANOTESLA_PER_TESLA",
    "KM_PER_M",
]

NANOTESLA_PER_TESLA = 1e9
KM_PER_M = 1e-3
NANOSECONDS_PER_SECOND = 1e9


def mrp_to_quaternion(sigma_BN: Any) -> np.ndarray:
    """Basilisk MRPs ``sigma_BN`` (shape ``(3,)`` or ``(N, 3)``) to pdcal quaternions
    ``(q_x, q_y, q_z, q_w)``, scalar last, with ``A(q) = [BN]`` (``v_B = A(q) v_N``).

    Either MRP set (the shadow set too) gives the same rotation; the result has ``q_w >= 0``.
    """
    sigma = np.asarray(sigma_BN, dtype=float)
    single = sigma.ndim == 1
    sigma = np.atleast_2d(sigma)
    if sigma.shape[-1] != 3:
        raise ValueError(f"sigma_BN must have 3 components per row, got shape {sigma.shape}")
    s2 = np.einsum("ij,ij->i", sigma, sigma)
    q = np.empty((sigma.shape[0], 4))
    q[:, :3] = 2.0 * sigma / (1.0 + s2)[:, None]
    q[:, 3] = (1.0 - s2) / (1.0 + s2)
    q[q[:, 3] < 0.0] *= -1.0
    return q[0] if single else q


def quaternion_to_dcm(q: Any) -> np.ndarray:
    """pdcal's attitude matrix ``A(q)`` (dataset-format.md) of a scalar-last quaternion:
    ``A = (q_w^2 - |q_v|^2) I + 2 q_v q_v^T - 2 q_w [q_v x]``."""
    q = np.asarray(q, dtype=float)
    qv, qw = q[:3], q[3]
    cross = np.array([[0.0, -qv[2], qv[1]], [qv[2], 0.0, -qv[0]], [-qv[1], qv[0], 0.0]])
    return (qw * qw - qv @ qv) * np.eye(3) + 2.0 * np.outer(qv, qv) - 2.0 * qw * cross


def normal_to_az_el_deg(n_B: Any) -> np.ndarray:
    """Body-frame normals (``(3,)`` or ``(M, 3)``, any length) to pdcal's
    ``(azimuth_deg, elevation_deg)``: azimuth from +x toward +y in (-180, 180], elevation
    toward +z in [-90, 90]."""
    n = np.asarray(n_B, dtype=float)
    single = n.ndim == 1
    n = np.atleast_2d(n)
    if n.shape[-1] != 3:
        raise ValueError(f"normals must have 3 components per row, got shape {n.shape}")
    norm = np.linalg.norm(n, axis=1)
    if np.any(~np.isfinite(norm)) or np.any(norm == 0.0):
        raise ValueError("a CSS normal is zero or not finite")
    u = n / norm[:, None]
    az = np.degrees(np.arctan2(u[:, 1], u[:, 0]))
    el = np.degrees(np.arcsin(np.clip(u[:, 2], -1.0, 1.0)))
    out = np.column_stack([az, el])
    return out[0] if single else out


def az_el_deg_to_normal(az_el_deg: Any) -> np.ndarray:
    """pdcal's ``(azimuth_deg, elevation_deg)`` to unit body-frame normals (Eq. 16)."""
    ae = np.asarray(az_el_deg, dtype=float)
    single = ae.ndim == 1
    ae = np.atleast_2d(ae)
    az, el = np.radians(ae[:, 0]), np.radians(ae[:, 1])
    n = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return n[0] if single else n


def epoch_utc_string(epoch: Any) -> str:
    """The simulation epoch (the instant of Basilisk time 0) as pdcal's ISO 8601 UTC string.

    Accepts a string already in that form (``2026-03-20T12:00:00Z``), a ``datetime`` (naive is
    taken as UTC), or a Basilisk epoch as a mapping with ``year, month, day, hours, minutes,
    seconds`` (the fields of ``EpochMsgPayload``).
    """
    if isinstance(epoch, str):
        if not epoch.endswith("Z"):
            raise ValueError(f"epoch_utc {epoch!r} must end with Z (UTC)")
        return epoch
    if isinstance(epoch, Mapping):
        seconds = float(epoch["seconds"])
        whole = int(np.floor(seconds))
        epoch = _dt.datetime(
            int(epoch["year"]), int(epoch["month"]), int(epoch["day"]),
            int(epoch["hours"]), int(epoch["minutes"]), whole,
            int(round((seconds - whole) * 1e6)),
        )
    if isinstance(epoch, _dt.datetime):
        if epoch.tzinfo is not None:
            epoch = epoch.astimezone(_dt.timezone.utc).replace(tzinfo=None)
        text = epoch.strftime("%Y-%m-%dT%H:%M:%S")
        if epoch.microsecond:
            text += f".{epoch.microsecond:06d}"
        return text + "Z"
    raise TypeError(f"cannot read an epoch from {type(epoch).__name__}")


def common_time_line(series: Mapping[str, Sequence[Any]]) -> tuple:
    """Recorders of tasks at different rates on one time line, for the bridge.

    ``series`` maps a name to ``(t_ns, values)`` (``recorder.times()`` and the recorded
    field, one row per time). Returns ``(t_ns, arrays)``: the sorted union of all times (ns,
    int64) and, per name, the values on it with NaN rows where that recorder has no sample
    (pdcal's blank cells). Times are matched exactly, as Basilisk's integer-ns task times
    are; a recorder with a repeated time is an error.
    """
    times = {}
    for name, (t_ns, values) in series.items():
        t = np.asarray(t_ns, dtype=np.int64)
        if t.ndim != 1 or np.any(np.diff(t) <= 0):
            raise ValueError(f"{name}: times must be one-dimensional and strictly increasing")
        times[name] = t
    union = np.unique(np.concatenate(list(times.values()))) if times else np.zeros(0, np.int64)
    arrays = {}
    for name, (_, values) in series.items():
        v = np.asarray(values, dtype=float)
        if v.shape[0] != times[name].shape[0]:
            raise ValueError(f"{name}: {v.shape[0]} rows for {times[name].shape[0]} times")
        out = np.full((union.shape[0],) + v.shape[1:], np.nan)
        out[np.searchsorted(union, times[name])] = v
        arrays[name] = out
    return union, arrays


def _rows(name: str, values: Any, n_rows: int, n_cols: int) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.ndim != 2 or a.shape[0] != n_rows or a.shape[1] < n_cols:
        raise ValueError(
            f"{name}: expected shape ({n_rows}, {n_cols}), got {a.shape}"
        )
    return a[:, :n_cols]


def _dcm(name: str, dcm: Optional[Any]) -> np.ndarray:
    if dcm is None:
        return np.eye(3)
    m = np.asarray(dcm, dtype=float).reshape(3, 3)
    if not np.allclose(m @ m.T, np.eye(3), atol=1e-9):
        raise ValueError(f"{name} is not a rotation matrix")
    return m


def dataset_kwargs_from_basilisk(
    *,
    epoch_utc: Any,
    css_cos_values: Any,
    css_normals_B: Any,
    imu_rate_platform_rad_s: Any,
    t_ns: Any = None,
    t_s: Any = None,
    tam_sensor_T: Any = None,
    r_BN_N_m: Any = None,
    tle: Optional[Sequence[str]] = None,
    imu_dcm_PB: Any = None,
    tam_dcm_SB: Any = None,
    css_fov_rad: Any = None,
    noise: Optional[Mapping[str, float]] = None,
    name: str = "basilisk",
    truth: Optional[Mapping[str, Any]] = None,
) -> dict:
    """The keyword arguments of ``pdcal.Dataset(...)`` from Basilisk recorder arrays.

    One row per sample time; a sensor not sampled at a row is NaN there (Basilisk recorders
    of tasks at other rates must be put on one time line first).

    * ``epoch_utc``: the UTC instant of Basilisk time 0 (see :func:`epoch_utc_string`).
    * ``t_ns`` (``recorder.times()``, ns) or ``t_s`` (s): sample times since that epoch.
    * ``css_cos_values``: ``CSSArraySensorMsg.CosValue`` rows ``(N, >= M)`` (the first M
      columns are used) or the ``CSSRawDataMsg.OutputData`` of M sensors stacked as columns;
      Basilisk has applied ``scaleFactor``, so these are volts when ``scaleFactor`` is.
    * ``css_normals_B``: ``(M, 3)`` the *nominal* CSS normals in the body frame (what the
      team believes; the calibration estimates the true ones). Becomes ``nominal_az_el_deg``.
    * ``imu_rate_platform_rad_s``: ``IMUSensorMsg.AngVelPlatform`` ``(N, 3)``, rad/s, rotated
      to the body frame with ``imu_dcm_PB`` (identity when None).
    * ``tam_sensor_T``: ``TAMSensorMsg.tam_S`` ``(N, 3)``, tesla, rotated with ``tam_dcm_SB``;
      None for photodiode-only data.
    * ``r_BN_N_m``: ``SCStatesMsg.r_BN_N`` ``(N, 3)``, metres, N taken as GCRF; or ``tle``.
    * ``css_fov_rad``: each CSS's ``fov`` (half angle, rad; one value for all or M values);
      becomes ``fov_deg``. None leaves the cosine law to 90 deg.
    * ``noise``: 1-sigma hints ``{"gyro_rad_s", "mag_nT", "photodiode_V"}`` in pdcal's units
      (a CSS ``senNoiseStd`` is in cosine units before ``scaleFactor``: multiply by it).
    * ``truth``: for simulations, :func:`truth_from_basilisk`'s dict (``pdcal.evaluate``).
    """
    if (t_ns is None) == (t_s is None):
        raise ValueError("give exactly one of t_ns and t_s")
    times_s = (
        np.asarray(t_ns, dtype=float) / NANOSECONDS_PER_SECOND
        if t_ns is not None
        else np.asarray(t_s, dtype=float)
    )
    if times_s.ndim != 1:
        raise ValueError(f"sample times must be one-dimensional, got shape {times_s.shape}")
    n = times_s.shape[0]
    normals = np.atleast_2d(np.asarray(css_normals_B, dtype=float))
    m = normals.shape[0]
    photodiodes_v = _rows("css_cos_values", css_cos_values, n, m)
    rate_p = _rows("imu_rate_platform_rad_s", imu_rate_platform_rad_s, n, 3)
    gyro_b = rate_p @ _dcm("imu_dcm_PB", imu_dcm_PB)
    kwargs: dict = {
        "epoch_utc": epoch_utc_string(epoch_utc),
        "t_s": times_s,
        "gyro_rad_s": gyro_b,
        "photodiodes_V": photodiodes_v,
        "nominal_az_el_deg": normal_to_az_el_deg(normals).reshape(m, 2),
    }
    if tam_sensor_T is not None:
        tam_s = _rows("tam_sensor_T", tam_sensor_T, n, 3)
        kwargs["mag_nT"] = (tam_s @ _dcm("tam_dcm_SB", tam_dcm_SB)) * NANOTESLA_PER_TESLA
    if (r_BN_N_m is None) == (tle is None):
        raise ValueError("give exactly one orbit: r_BN_N_m or tle")
    if r_BN_N_m is not None:
        kwargs["positions_gcrf_km"] = _rows("r_BN_N_m", r_BN_N_m, n, 3) * KM_PER_M
    else:
        line1, line2 = tle
        kwargs["tle"] = (line1, line2)
    if css_fov_rad is not None:
        fov_deg = np.degrees(np.broadcast_to(np.asarray(css_fov_rad, dtype=float), (m,))).copy()
        kwargs["fov_deg"] = fov_deg
    if noise is not None:
        kwargs["noise"] = dict(noise)
    kwargs["name"] = name
    if truth is not None:
        kwargs["truth"] = dict(truth)
    return kwargs


def truth_from_basilisk(
    *,
    t_ns: Any,
    sigma_BN: Any,
    omega_BN_B_rad_s: Any,
    r_BN_N_m: Any,
    r_sun_N_m: Any,
    shadow_factor: Any,
    mag_field_N_T: Any,
    gyro_bias_platform_rad_s: Any,
    css_true_normals_B: Any,
    css_scale_factors: Any,
    imu_dcm_PB: Any = None,
    effects: Sequence[str] = (),
) -> dict:
    """The ``truth`` of a simulated ``pdcal.Dataset`` (what ``pdcal.evaluate`` compares
    against) from Basilisk's own states: ``SCStatesMsg`` (``sigma_BN``, ``omega_BN_B``,
    ``r_BN_N``), the Sun's ``SpicePlanetStateMsg.PositionVector`` (``r_sun_N_m``, m, one row
    or one per sample), ``EclipseMsg.shadowFactor``, ``MagneticFieldMsg.magField_N`` (T), the
    IMU's ``senRotBias`` (platform frame) and the CSS configuration actually simulated
    (``nHat_B``, ``scaleFactor``). ``effects``: truth.ron effect spellings, e.g.
    ``["Albedo(map: \"toms-mean-1p25x1\")"]`` when Basilisk's albedo used that map.
    """
    t_s = np.asarray(t_ns, dtype=float) / NANOSECONDS_PER_SECOND
    n = t_s.shape[0]
    q = mrp_to_quaternion(_rows("sigma_BN", sigma_BN, n, 3))
    dcm_bn = np.stack([quaternion_to_dcm(qk) for qk in q])
    r_n = _rows("r_BN_N_m", r_BN_N_m, n, 3)
    sun_n = np.broadcast_to(np.asarray(r_sun_N_m, dtype=float), (n, 3))
    to_sun = sun_n - r_n
    to_sun = to_sun / np.linalg.norm(to_sun, axis=1)[:, None]
    mag_n = _rows("mag_field_N_T", mag_field_N_T, n, 3)
    bias_p = np.broadcast_to(np.asarray(gyro_bias_platform_rad_s, dtype=float), (n, 3))
    scale = np.asarray(css_scale_factors, dtype=float)
    az_el = normal_to_az_el_deg(np.atleast_2d(np.asarray(css_true_normals_B, dtype=float)))
    return {
        "t_s": t_s,
        "q_xyzw": q,
        "w_body_rad_s": _rows("omega_BN_B_rad_s", omega_BN_B_rad_s, n, 3),
        "gyro_bias_rad_s": bias_p @ _dcm("imu_dcm_PB", imu_dcm_PB),
        "sun_body": np.einsum("kij,kj->ki", dcm_bn, to_sun),
        "eclipse": np.asarray(shadow_factor, dtype=float).reshape(n),
        "r_gcrf_km": r_n * KM_PER_M,
        "mag_body_nT": np.einsum("kij,kj->ki", dcm_bn, mag_n) * NANOTESLA_PER_TESLA,
        "scale_V": scale,
        "azimuth_deg": az_el[:, 0],
        "elevation_deg": az_el[:, 1],
        "effects": list(effects),
    }


def dataset_from_basilisk(**kwargs: Any):
    """A ``pdcal.Dataset`` from Basilisk recorder arrays; the arguments are those of
    :func:`dataset_kwargs_from_basilisk`."""
    from . import Dataset

    return Dataset(**dataset_kwargs_from_basilisk(**kwargs))

"""pdcal.basilisk: the conversions, and a real Basilisk simulation calibrated by pdcal.

The conversion tests need only numpy. The simulation tests need the ``bsk`` package; the
end-to-end test needs the native ``pdcal`` too. Each skips cleanly without them (CI installs
both). Run as a script to time the simulation and write its arrays:
``python crates/python/tests/test_basilisk.py OUT.npz [SEED]``.
"""

from __future__ import annotations

import datetime as dt
import importlib.util
import math
import os
import pathlib
import sys
import tempfile
import time

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
# The pure-Python module is importable from the source tree without the native package.
_BASILISK_PY = REPO / "crates" / "python" / "python" / "pdcal" / "basilisk.py"
_spec = importlib.util.spec_from_file_location("pdcal_basilisk_source", _BASILISK_PY)
bridge = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bridge)

ARCSEC = math.pi / (180.0 * 3600.0)
AU_KM = 149_597_870.7
JD_J2000 = 2_451_545.0
# TAI - UTC since 2017-01-01 (no leap second announced after it) plus TT - TAI.
TT_MINUS_UTC_S = 37.0 + 32.184


def have_basilisk() -> bool:
    return importlib.util.find_spec("Basilisk") is not None


# ----------------------------------------------------------------------------------------
# Reference frames and the Sun, as pdcal computes them (crates/ephem: frames.rs, sun.rs),
# so that the Sun and Earth messages written for Basilisk agree with pdcal's references.
# ----------------------------------------------------------------------------------------


def _rot1(a):
    s, c = math.sin(a), math.cos(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def _rot2(a):
    s, c = math.sin(a), math.cos(a)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def _rot3(a):
    s, c = math.sin(a), math.cos(a)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def _jd_utc(t: dt.datetime) -> float:
    return (t - dt.datetime(2000, 1, 1, 12)).total_seconds() / 86400.0 + JD_J2000


def _centuries_tt(t: dt.datetime) -> float:
    if t < dt.datetime(2017, 1, 1):
        raise ValueError("TT - UTC here is only right from 2017 on")
    return (_jd_utc(t) + TT_MINUS_UTC_S / 86400.0 - JD_J2000) / 36525.0


def _frame_bias():
    return _rot1(0.006_819 * ARCSEC) @ _rot2(-0.016_617 * ARCSEC) @ _rot3(-0.0146 * ARCSEC)


def _precession_iau76(tc):
    zeta = ((0.017_998 * tc + 0.301_88) * tc + 2306.2181) * tc * ARCSEC
    theta = ((-0.041_833 * tc - 0.426_65) * tc + 2004.3109) * tc * ARCSEC
    z = ((0.018_203 * tc + 1.094_68) * tc + 2306.2181) * tc * ARCSEC
    return _rot3(-z) @ _rot2(theta) @ _rot3(-zeta)


# The six largest IAU-1980 nutation terms (0.1 mas units): the rest move the pole by < 0.1".
_NUTATION = [
    ((0, 0, 0, 0, 1), -171_996.0, -174.2, 92_025.0, 8.9),
    ((0, 0, 2, -2, 2), -13_187.0, -1.6, 5_736.0, -3.1),
    ((0, 0, 2, 0, 2), -2_274.0, -0.2, 977.0, -0.5),
    ((0, 0, 0, 0, 2), 2_062.0, 0.2, -895.0, 0.5),
    ((0, 1, 0, 0, 0), 1_426.0, -3.4, 54.0, -0.1),
    ((1, 0, 0, 0, 0), 712.0, 0.1, -7.0, 0.0),
]


def _nutation(tc):
    def poly(c0, c1, c2, c3, revs):
        arcsec = ((c3 * tc + c2) * tc + c1) * tc + c0
        return ((arcsec + ((revs * tc) % 1.0) * 1_296_000.0) * ARCSEC) % (2 * math.pi)

    args = [
        poly(485_866.733, 715_922.633, 31.310, 0.064, 1325.0),
        poly(1_287_099.804, 1_292_581.224, -0.577, -0.012, 99.0),
        poly(335_778.877, 295_263.137, -13.257, 0.011, 1342.0),
        poly(1_072_261.307, 1_105_601.328, -6.891, 0.019, 1236.0),
        poly(450_160.280, -482_890.539, 7.455, 0.008, -5.0),
    ]
    dpsi = deps = 0.0
    for m, a, a_t, b, b_t in _NUTATION:
        arg = sum(k * x for k, x in zip(m, args))
        dpsi += (a + a_t * tc) * math.sin(arg)
        deps += (b + b_t * tc) * math.cos(arg)
    dpsi *= 1e-4 * ARCSEC
    deps *= 1e-4 * ARCSEC
    eps = (((0.001_813 * tc - 0.000_59) * tc - 46.8150) * tc + 84_381.448) * ARCSEC
    n = _rot1(-(eps + deps)) @ _rot3(-dpsi) @ _rot1(eps)
    eqeq = dpsi * math.cos(eps) + (0.002_64 * math.sin(args[4])) * ARCSEC
    return n, eqeq


def _gmst82(t: dt.datetime) -> float:
    tu = (_jd_utc(t) - JD_J2000) / 36525.0
    seconds = (
        67_310.548_41
        + (876_600.0 * 3600.0 + 8_640_184.812_866) * tu
        + 0.093_104 * tu * tu
        - 6.2e-6 * tu**3
    )
    return (seconds % 86_400.0) / 86_400.0 * 2 * math.pi


def gcrf_to_itrf(t: dt.datetime) -> np.ndarray:
    """``v_itrf = R v_gcrf`` (UT1 = UTC, no polar motion): Basilisk's ``J20002Pfix``."""
    tc = _centuries_tt(t)
    n, eqeq = _nutation(tc)
    return _rot3(_gmst82(t) + eqeq) @ n @ _precession_iau76(tc) @ _frame_bias()


def sun_gcrf_km(t: dt.datetime) -> np.ndarray:
    """Geocentric Sun, GCRF, km: pdcal's LowPrecisionSun (Astronomical Almanac, aberration
    removed, precessed to J2000, frame bias), the formula pdcal itself evaluates."""
    tc = _centuries_tt(t)
    n = tc * 36525.0
    l_deg = 280.460 + 0.985_647_4 * n
    g = math.radians(357.528 + 0.985_600_3 * n)
    lam = math.radians(l_deg + 1.915 * math.sin(g) + 0.020 * math.sin(2 * g))
    lam += 20.495_52 * ARCSEC
    eps = math.radians(23.439 - 0.000_000_4 * n)
    r = (1.000_14 - 0.016_71 * math.cos(g) - 0.000_14 * math.cos(2 * g)) * AU_KM
    mod = r * np.array([math.cos(lam), math.cos(eps) * math.sin(lam), math.sin(eps) * math.sin(lam)])
    return (_precession_iau76(tc) @ _frame_bias()).T @ mod


def write_wmm_cof_from_igrf(shc_path: pathlib.Path, out_path: pathlib.Path) -> None:
    """A ``WMM.COF`` holding IGRF-14 (2025.0 coefficients, 2025-2030 secular variation,
    degree 13) so that Basilisk's WMM module evaluates the field pdcal references.

    IGRF-14's 2030 column is the 2025 value plus five years of secular variation, so the
    WMM form ``g(t) = g(2025) + (t - 2025) gdot`` reproduces IGRF between 2025 and 2030.
    """
    lines = [ln for ln in shc_path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    epochs = [float(x) for x in lines[1].split()]
    i25, i30 = epochs.index(2025.0), epochs.index(2030.0)
    g, h = {}, {}
    for ln in lines[2:]:
        f = ln.split()
        n, m = int(f[0]), int(f[1])
        vals = [float(x) for x in f[2:]]
        pair = (vals[i25], (vals[i30] - vals[i25]) / 5.0)
        (g if m >= 0 else h)[(n, abs(m))] = pair
    out = ["    2025.0            IGRF14-2025     01/01/2025"]
    for (n, m) in sorted(g):
        gv, gd = g[(n, m)]
        hv, hd = h.get((n, m), (0.0, 0.0))
        out.append(f"{n:3d}{m:3d}{gv:11.2f}{hv:11.2f}{gd:11.2f}{hd:11.2f}")
    out += ["9" * 48, "9" * 48]
    out_path.write_text("\n".join(out) + "\n")


# ----------------------------------------------------------------------------------------
# The Basilisk simulation: a 3U CubeSat tumbling in a sunlit LEO.
# ----------------------------------------------------------------------------------------

EPOCH = dt.datetime(2026, 3, 20, 12, 0, 0)
# Nominal CSS layout (az, el) in degrees: one on each face of the 3U plus two canted ones on
# the long faces, as a team might wedge them.
NOMINAL_AZ_EL_DEG = np.array(
    [
        [0.0, 0.0],
        [180.0, 0.0],
        [90.0, 0.0],
        [-90.0, 0.0],
        [0.0, 90.0],
        [0.0, -90.0],
        [45.0, 30.0],
        [-135.0, -30.0],
    ]
)
NOMINAL_SCALE_V = 2.5
CSS_NOISE_COS = 0.004  # 1-sigma before scaleFactor: 10 mV at 2.5 V
GYRO_NOISE_RAD_S = 5e-4
GYRO_BIAS_RAD_S = np.array([0.004, -0.003, 0.002])
TAM_NOISE_T = 150e-9


def true_css_config(seed: int):
    """Perturbed normals (a few deg) and scale factors (a few %), seeded."""
    rng = np.random.default_rng(seed)
    m = NOMINAL_AZ_EL_DEG.shape[0]
    nominal_n = bridge.az_el_deg_to_normal(NOMINAL_AZ_EL_DEG)
    true_n = np.empty_like(nominal_n)
    for i, n in enumerate(nominal_n):
        # a tilt of 2-5 deg in a random direction about the nominal normal
        tilt = math.radians(rng.uniform(2.0, 5.0))
        a = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(n, a)
        phi = rng.uniform(0, 2 * math.pi)
        axis = math.cos(phi) * a + math.sin(phi) * b
        true_n[i] = math.cos(tilt) * n + math.sin(tilt) * np.cross(axis, n)
    true_scale = NOMINAL_SCALE_V * (1.0 + rng.uniform(-0.06, 0.06, m))
    return nominal_n, true_n / np.linalg.norm(true_n, axis=1)[:, None], true_scale


def run_basilisk_sim(seed: int = 1, duration_s: float = 2400.0, albedo_model: str = "average",
                     workdir: pathlib.Path | None = None) -> dict:
    """Runs the simulation and returns the recorder arrays and the true CSS configuration.

    ``albedo_model``: ``"average"`` (Basilisk's constant-albedo planet, ALB 0.3),
    ``"toms"`` (the TOMS map pdcal uses, given to Basilisk's data model) or ``"none"``.
    """
    from Basilisk.architecture import messaging
    from Basilisk.simulation import (albedo, coarseSunSensor, eclipse, imuSensor,
                                     magneticFieldWMM, magnetometer, spacecraft)
    from Basilisk.utilities import SimulationBaseClass, macros, orbitalMotion, simIncludeGravBody

    rng = np.random.default_rng(1000 + seed)
    nominal_n, true_n, true_scale = true_css_config(seed)
    tmp = pathlib.Path(workdir or tempfile.mkdtemp(prefix="pdcal-bsk-"))

    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("proc")
    step_ns = macros.sec2nano(1.0)
    proc.addTask(sim.CreateNewTask("task", step_ns))

    sc = spacecraft.Spacecraft()
    sc.ModelTag = "cubesat3u"
    mass = 4.0
    sc.hub.mHub = mass
    # A 3U with one deployed panel: three distinct principal moments, kg m^2
    sc.hub.IHubPntBc_B = [[0.036, 0.0004, 0.0], [0.0004, 0.028, 0.0002], [0.0, 0.0002, 0.010]]

    grav = simIncludeGravBody.gravBodyFactory()
    earth = grav.createEarth()
    earth.isCentralBody = True
    grav.addBodiesTo(sc)
    mu = earth.mu

    t0 = EPOCH
    sun_km = sun_gcrf_km(t0 + dt.timedelta(seconds=duration_s / 2))
    s_hat = sun_km / np.linalg.norm(sun_km)
    # Sun-synchronous inclination; the node puts the Sun 68 deg from the orbit plane, so the
    # orbit stays sunlit and Earth albedo is seen from the day side.
    oe = orbitalMotion.ClassicElements()
    oe.a = (6378.137 + 550.0) * 1000.0
    oe.e = 0.0005
    oe.i = math.radians(97.6)
    beta = math.radians(68.0)
    sun_ra = math.atan2(s_hat[1], s_hat[0])
    # choose the node so that the orbit normal h leans toward the Sun by 90 - beta
    best = min(
        (abs(math.asin(np.clip(np.dot(
            [math.sin(oe.i) * math.sin(om), -math.sin(oe.i) * math.cos(om), math.cos(oe.i)],
            s_hat), -1, 1)) - beta), om)
        for om in np.radians(np.arange(0.0, 360.0, 0.25))
    )
    oe.Omega = best[1] - 0.0 * sun_ra
    oe.omega = math.radians(30.0)
    oe.f = math.radians(rng.uniform(0, 360))
    r_n, v_n = orbitalMotion.elem2rv(mu, oe)
    sc.hub.r_CN_NInit = r_n
    sc.hub.v_CN_NInit = v_n
    sc.hub.sigma_BNInit = list(rng.uniform(-0.3, 0.3, 3))
    # Near the intermediate axis (y): the tumble flips over and turns every face to the Sun.
    w0 = np.array([rng.uniform(0.1, 0.3), 1.0, rng.uniform(0.1, 0.3)]) * rng.choice([-1.0, 1.0], 3)
    w0 *= math.radians(rng.uniform(3.0, 5.0)) / np.linalg.norm(w0)
    sc.hub.omega_BN_BInit = list(w0)
    sim.AddModelToTask("task", sc, 10)

    def planet_payload(name, pos_m, t):
        p = messaging.SpicePlanetStatePayload() if hasattr(messaging, "SpicePlanetStatePayload") else messaging.SpicePlanetStateMsgPayload()
        p.PlanetName = name
        p.PositionVector = list(pos_m)
        p.VelocityVector = [0.0, 0.0, 0.0]
        p.J20002Pfix = gcrf_to_itrf(t).tolist() if name == "earth" else np.eye(3).tolist()
        return p

    sun_msg = messaging.SpicePlanetStateMsg().write(planet_payload("sun", sun_gcrf_km(t0) * 1e3, t0))
    earth_msg = messaging.SpicePlanetStateMsg().write(planet_payload("earth", [0.0, 0.0, 0.0], t0))

    ecl = eclipse.Eclipse()
    ecl.sunInMsg.subscribeTo(sun_msg)
    ecl.addPlanetToModel(earth_msg)
    ecl.addSpacecraftToModel(sc.scStateOutMsg)
    sim.AddModelToTask("task", ecl, 9)

    alb = None
    if albedo_model != "none":
        alb = albedo.Albedo()
        alb.ModelTag = "albedo"
        if albedo_model == "average":
            alb.addPlanetandAlbedoAverageModel(earth_msg, 0.3, 90, 180)
        elif albedo_model == "toms":
            path = tmp / "toms_1p25x1_fraction.csv"
            write_toms_as_basilisk_csv(REPO / "fixtures" / "albedo" / "earthReflectivityMean_1p25x1.dat", path)
            alb.addPlanetandAlbedoDataModel(earth_msg, str(tmp) + "/", path.name)
        else:
            raise ValueError(f"albedo_model {albedo_model!r}")
        alb.spacecraftStateInMsg.subscribeTo(sc.scStateOutMsg)
        alb.sunPositionInMsg.subscribeTo(sun_msg)
        for n in true_n:
            alb.addInstrumentConfig(math.pi / 2, list(n), [0.0, 0.0, 0.0])
        sim.AddModelToTask("task", alb, 8)

    sensors = []
    array = coarseSunSensor.CSSConstellation()
    array.ModelTag = "cssArray"
    for i, (n, c) in enumerate(zip(true_n, true_scale)):
        css = coarseSunSensor.CoarseSunSensor()
        css.ModelTag = f"css{i + 1}"
        css.nHat_B = list(n)
        css.scaleFactor = float(c)
        css.fov = math.pi / 2
        css.kellyFactor = 0.0
        css.senNoiseStd = CSS_NOISE_COS
        css.RNGSeed = 7 * seed + i + 11
        css.maxOutput = 10.0
        css.sunInMsg.subscribeTo(sun_msg)
        css.stateInMsg.subscribeTo(sc.scStateOutMsg)
        css.sunEclipseInMsg.subscribeTo(ecl.eclipseOutMsgs[0])
        if alb is not None:
            css.albedoInMsg.subscribeTo(alb.albOutMsgs[i])
        sensors.append(css)
    array.sensorList = coarseSunSensor.CSSVector(sensors)
    sim.AddModelToTask("task", array, 7)

    imu = imuSensor.ImuSensor()
    imu.ModelTag = "imu"
    imu.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    imu.senRotBias = list(GYRO_BIAS_RAD_S)
    imu.setAMatrixGyro(np.zeros((3, 3)).tolist())  # white noise, no Gauss-Markov memory
    imu.PMatrixGyro = (np.eye(3) * GYRO_NOISE_RAD_S).tolist()
    imu.setWalkBoundsGyro([1.0, 1.0, 1.0])
    imu.RNGSeed = 100 + seed
    sim.AddModelToTask("task", imu, 7)

    cof = tmp / "WMM.COF"
    write_wmm_cof_from_igrf(REPO / "fixtures" / "igrf" / "IGRF14.shc", cof)
    wmm = magneticFieldWMM.MagneticFieldWMM()
    wmm.ModelTag = "igrf14"
    wmm.configureWMMFile(str(cof))
    epoch_payload = messaging.EpochMsgPayload()
    epoch_payload.year, epoch_payload.month, epoch_payload.day = t0.year, t0.month, t0.day
    epoch_payload.hours, epoch_payload.minutes, epoch_payload.seconds = t0.hour, t0.minute, float(t0.second)
    epoch_msg = messaging.EpochMsg().write(epoch_payload)
    wmm.epochInMsg.subscribeTo(epoch_msg)
    wmm.planetPosInMsg.subscribeTo(earth_msg)
    wmm.addSpacecraftToModel(sc.scStateOutMsg)
    sim.AddModelToTask("task", wmm, 9)

    tam = magnetometer.Magnetometer()
    tam.ModelTag = "tam"
    tam.stateInMsg.subscribeTo(sc.scStateOutMsg)
    tam.magInMsg.subscribeTo(wmm.envOutMsgs[0])
    tam.senNoiseStd = [TAM_NOISE_T] * 3
    tam.RNGSeed = 200 + seed
    sim.AddModelToTask("task", tam, 7)

    rec = {
        "sc": sc.scStateOutMsg.recorder(),
        "css": array.constellationOutMsg.recorder(),
        "imu": imu.sensorOutMsg.recorder(),
        "tam": tam.tamDataOutMsg.recorder(),
        "mag": wmm.envOutMsgs[0].recorder(),
        "ecl": ecl.eclipseOutMsgs[0].recorder(),
    }
    if alb is not None:
        for i in range(len(true_n)):
            rec[f"alb{i}"] = alb.albOutMsgs[i].recorder()
    for r in rec.values():
        sim.AddModelToTask("task", r)

    sim.InitializeSimulation()
    started = time.perf_counter()
    steps = int(round(duration_s))
    for k in range(1, steps + 1):
        # the Sun and the Earth's orientation at the step about to run
        t = t0 + dt.timedelta(seconds=k - 1)
        if (k - 1) % 60 == 0:
            sun_msg.write(planet_payload("sun", sun_gcrf_km(t) * 1e3, t), macros.sec2nano(k - 1))
        earth_msg.write(planet_payload("earth", [0.0, 0.0, 0.0], t), macros.sec2nano(k - 1))
        sim.ConfigureStopTime(macros.sec2nano(float(k)))
        sim.ExecuteSimulation()
    run_s = time.perf_counter() - started

    n_css = len(true_n)
    # The IMU writes zeros at time 0 (it differences the state since its previous call), so
    # the first row is left out of every series.
    keep = slice(1, None)
    out = {
        "epoch_utc": bridge.epoch_utc_string(t0),
        "t_ns": rec["css"].times()[keep],
        "css_cos_values": rec["css"].CosValue[:, :n_css][keep],
        "imu_rate_platform_rad_s": rec["imu"].AngVelPlatform[keep],
        "tam_sensor_T": rec["tam"].tam_S[keep],
        "r_BN_N_m": rec["sc"].r_BN_N[keep],
        "sigma_BN": rec["sc"].sigma_BN[keep],
        "omega_BN_B": rec["sc"].omega_BN_B[keep],
        "mag_field_N_T": rec["mag"].magField_N[keep],
        "shadow_factor": rec["ecl"].shadowFactor[keep],
        "nominal_normals_B": nominal_n,
        "true_normals_B": true_n,
        "true_scale_V": true_scale,
        "run_s": np.array(run_s),
    }
    if alb is not None:
        out["albedo_at_instrument"] = np.column_stack(
            [rec[f"alb{i}"].albedoAtInstrument for i in range(n_css)])[keep]
    return out


def write_toms_as_basilisk_csv(dat_path: pathlib.Path, out_path: pathlib.Path) -> None:
    """The TOMS map of pdcal's fixtures in the layout of Basilisk's CSV loader (row =
    latitude from the south, column = longitude from -180, fraction; fixtures/albedo/README)."""
    dat = np.loadtxt(dat_path)  # 288 lon x 180 lat (north first), percent
    refl = dat[:, ::-1].T / 100.0
    np.savetxt(out_path, refl, delimiter=",", fmt="%.6f")


NOISE_HINTS = {
    "gyro_rad_s": GYRO_NOISE_RAD_S,
    "mag_nT": TAM_NOISE_T * 1e9,
    "photodiode_V": CSS_NOISE_COS * NOMINAL_SCALE_V,
}


def bridge_kwargs(sim_out: dict) -> dict:
    return bridge.dataset_kwargs_from_basilisk(
        epoch_utc=sim_out["epoch_utc"],
        t_ns=sim_out["t_ns"],
        css_cos_values=sim_out["css_cos_values"],
        css_normals_B=sim_out["nominal_normals_B"],
        imu_rate_platform_rad_s=sim_out["imu_rate_platform_rad_s"],
        tam_sensor_T=sim_out["tam_sensor_T"],
        r_BN_N_m=sim_out["r_BN_N_m"],
        noise=NOISE_HINTS,
    )


if __name__ == "__main__":
    out_path = pathlib.Path(sys.argv[1])
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    model = sys.argv[3] if len(sys.argv) > 3 else "average"
    wall = time.perf_counter()
    res = run_basilisk_sim(seed=seed, albedo_model=model)
    print(f"simulation {float(res['run_s']):.1f} s, total {time.perf_counter() - wall:.1f} s")
    np.savez(out_path, **res)

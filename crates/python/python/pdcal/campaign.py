"""Campaigns: Monte Carlo design studies and fleet calibrations on Dask.

A *design study* runs, for each seed, what ``cargo xtask sim-calibrate`` runs for a seed
(simulate -> calibrate -> evaluate, the Rust function ``pdcal::sim_calibrate::run_seed``),
on a scenario whose parameters are drawn per run from the campaign's dispersions. A *fleet*
calibrates dataset directories independently, each into its own output. Both go to Dask
workers (``dask.distributed``): an in-process ``LocalCluster`` by default, or any cluster
through a ``Client`` or a scheduler address. The description and the table are documented
in ``docs/campaign.md``.

    >>> import pdcal.campaign
    >>> table = pdcal.campaign.run({"scenario": "rax2-like", "seeds": [1, 2, 3, 4]}, "out")

Command line: ``python -m pdcal.campaign SPEC --out DIR [--scheduler ADDRESS] [--workers N]``.
"""

from __future__ import annotations

import copy
import datetime
import glob as globmod
import html
import json
import math
import os
import pathlib
import sys
import tempfile
import time
import traceback
import zlib
from typing import Any, Callable, Iterable, Optional

import numpy as np

__all__ = [
    "DISPERSIONS",
    "load",
    "tasks",
    "draw",
    "scenario_for",
    "run_task",
    "run",
    "summary",
    "main",
]

TABLE = "results.parquet"
CSV = "results.csv"
SPEC = "campaign.json"
INDEX = "index.html"
SUMMARY_MD = "summary.md"

KEYS_DESIGN = {
    "name",
    "scenario",
    "overrides",
    "dispersions",
    "seeds",
    "draw_seed",
    "config",
    "photodiode_only",
    "cut",
    "sets",
    "diagnose",
    "keep_runs",
}
KEYS_FLEET = {"name", "fleet", "config", "smoother", "diagnose", "keep_runs"}

# The figures of merit of xtask sim-calibrate's results.json, flattened: a pair there is two
# columns here (`segments` [count, lost] -> `segments`, `segments_lost`).
FIGURES = [
    "worst_normal_deg",
    "worst_scale_percent",
    "attitude_rms_deg",
    "attitude_settled_rms_deg",
    "segments",
    "segments_lost",
    "first_lost_row",
    "first_lost",
    "best_single_normal_deg",
    "best_single_scale_percent",
    "final_inside",
    "final_states",
    "residual_inside",
    "magnitude_mean",
    "magnitude_std",
    "converged",
    "runtime_s",
    "verdict",
    "calibrated_states",
    "calibrated_outside_3sigma",
    "weakly_determined_states",
    "weakly_determined_outside_3sigma",
    "not_determined_states",
    "not_determined_outside_3sigma",
    "attitude_about_sun_inside",
    "attitude_across_sun_inside",
    "smoothed_attitude_about_sun_inside",
    "smoothed_attitude_across_sun_inside",
    "gyro_bias_inside",
    "repeatability",
    "repeat_differing",
    "bias_change_warnings",
    "repeat_tests_beyond_3",
    "repeat_tests",
    "repeat_rms_z",
    "about_sun_probes",
    "about_sun_turned",
    "about_sun_undecided",
    "dynamics",
    "gyro_rate_chi_square_per_dof",
    "normals_rotation_deg",
    "normals_rotation_chi_square",
    "normals_rotation_explained",
    "normals_turned",
    "mounting_warning",
    "sigma_factor",
]

_DEG = math.pi / 180.0
_MU_EARTH_KM3_S2 = 398600.4418
_R_EARTH_KM = 6378.137


# ---------------------------------------------------------------- the description


def load(spec: Any) -> dict:
    """A campaign description as a checked dict: a dict, or a path to a ``.ron`` or
    ``.json`` file. Raises ValueError naming the first unknown key or bad value."""
    if isinstance(spec, (str, os.PathLike)):
        path = pathlib.Path(spec)
        text = path.read_text()
        if path.suffix == ".ron":
            from ._pdcal import ron_to_json

            try:
                spec = json.loads(ron_to_json(text))
            except ValueError as e:
                raise ValueError(f"{path}: {e}") from None
        else:
            spec = json.loads(text)
        base = path.parent
    else:
        base = pathlib.Path.cwd()
        spec = copy.deepcopy(spec)
    if not isinstance(spec, dict):
        raise ValueError("a campaign is a dict (or a RON struct)")
    if "fleet" in spec:
        unknown = set(spec) - KEYS_FLEET
        if unknown:
            raise ValueError(f"fleet campaign: unknown key {sorted(unknown)[0]!r}")
        spec.setdefault("name", "fleet")
        spec["fleet"] = _fleet_dirs(spec["fleet"], base)
        spec.setdefault("config", None)
        spec.setdefault("smoother", True)
        spec.setdefault("diagnose", False)
        spec["keep_runs"] = True
        if spec["config"] is not None:
            spec["config"] = str((base / spec["config"]).resolve())
        return spec
    unknown = set(spec) - KEYS_DESIGN
    if unknown:
        raise ValueError(f"campaign: unknown key {sorted(unknown)[0]!r}")
    spec.setdefault("name", "campaign")
    spec.setdefault("scenario", "rax2-like")
    if isinstance(spec["scenario"], str) and spec["scenario"].endswith(".ron"):
        spec["scenario"] = str((base / spec["scenario"]).resolve())
    spec.setdefault("overrides", {})
    spec.setdefault("dispersions", {})
    spec["seeds"] = _seeds(spec.get("seeds", [1]))
    spec.setdefault("draw_seed", 0)
    spec.setdefault("config", None)
    if spec["config"] is not None:
        spec["config"] = str((base / spec["config"]).resolve())
    spec.setdefault("photodiode_only", False)
    spec.setdefault("cut", None)
    spec.setdefault("sets", 1)
    spec.setdefault("diagnose", False)
    spec.setdefault("keep_runs", False)
    for name, law in spec["dispersions"].items():
        if name not in DISPERSIONS and not name.startswith("scenario."):
            raise ValueError(
                f"dispersion {name!r}: expected one of {sorted(DISPERSIONS)} or scenario.<path>"
            )
        _check_law(name, law)
    # Fails here, on the client, rather than on every worker.
    scenario_for(spec, {})
    return spec


def _seeds(value: Any) -> list:
    if isinstance(value, int):
        seeds = list(range(1, value + 1))
    elif isinstance(value, dict):
        first = int(value.get("first", 1))
        seeds = list(range(first, first + int(value["count"])))
    else:
        seeds = [int(s) for s in value]
    if not seeds or any(s < 0 for s in seeds) or len(set(seeds)) != len(seeds):
        raise ValueError("seeds: distinct non-negative integers, at least one")
    return seeds


def _fleet_dirs(value: Any, base: pathlib.Path) -> list:
    patterns = [value] if isinstance(value, str) else list(value)
    dirs = []
    for pattern in patterns:
        full = str(base / pattern)
        found = sorted(globmod.glob(full)) if globmod.has_magic(full) else [full]
        if not found:
            raise ValueError(f"fleet: {pattern!r} matches no directory")
        dirs.extend(str(pathlib.Path(d).resolve()) for d in found)
    if len(set(dirs)) != len(dirs):
        raise ValueError("fleet: a dataset directory is listed twice")
    return dirs


def _check_law(name: str, law: Any) -> None:
    if not isinstance(law, dict) or len(law) != 1:
        raise ValueError(
            f"dispersion {name!r}: one of {{uniform: [lo, hi]}}, {{log_uniform: [lo, hi]}}, "
            f"{{normal: [mean, sigma]}}, {{choice: [...]}}"
        )
    (kind, args), = law.items()
    if kind in ("uniform", "log_uniform", "normal"):
        if len(args) != 2 or not all(isinstance(a, (int, float)) for a in args):
            raise ValueError(f"dispersion {name!r}: {kind} takes two numbers")
        lo, hi = args
        if kind == "uniform" and not lo <= hi:
            raise ValueError(f"dispersion {name!r}: uniform needs lo <= hi")
        if kind == "log_uniform" and not 0 < lo <= hi:
            raise ValueError(f"dispersion {name!r}: log_uniform needs 0 < lo <= hi")
        if kind == "normal" and not hi >= 0:
            raise ValueError(f"dispersion {name!r}: normal needs sigma >= 0")
    elif kind == "choice":
        if not isinstance(args, list) or not args:
            raise ValueError(f"dispersion {name!r}: choice takes a non-empty list")
    else:
        raise ValueError(f"dispersion {name!r}: unknown law {kind!r}")


# ---------------------------------------------------------------- the runs


def run_id(seed: int) -> str:
    """The run id of a design study's seed."""
    return f"seed-{seed:06d}"


def tasks(spec: dict) -> list:
    """The runs of a checked description: dicts with ``run_id`` and what the run needs."""
    if "fleet" in spec:
        out, seen = [], {}
        for d in spec["fleet"]:
            base = pathlib.Path(d).name or "dataset"
            seen[base] = seen.get(base, 0) + 1
            rid = base if seen[base] == 1 else f"{base}-{seen[base]}"
            out.append({"run_id": rid, "dataset": d})
        return out
    return [{"run_id": run_id(s), "seed": s} for s in spec["seeds"]]


def draw(spec: dict, seed: int) -> dict:
    """The dispersed parameters of seed ``seed``: each from its own random stream, keyed by
    the campaign's ``draw_seed``, the seed and the parameter's name, so the same seed draws
    the same values on any worker, and adding a dispersion leaves the others' draws alone."""
    params = {}
    for name in sorted(spec["dispersions"]):
        (kind, args), = spec["dispersions"][name].items()
        key = zlib.crc32(name.encode())
        rng = np.random.default_rng([int(spec["draw_seed"]), int(seed), key])
        if kind == "uniform":
            value = float(rng.uniform(args[0], args[1]))
        elif kind == "log_uniform":
            value = float(math.exp(rng.uniform(math.log(args[0]), math.log(args[1]))))
        elif kind == "normal":
            value = float(rng.normal(args[0], args[1]))
        else:
            value = args[int(rng.integers(len(args)))]
        params[name] = value
    return params


def _set_path(d: dict, path: str, value: Any) -> None:
    keys = path.split(".")
    for k in keys[:-1]:
        if k not in d or not isinstance(d[k], dict):
            raise ValueError(f"scenario has no {path!r}")
        d = d[k]
    if keys[-1] not in d:
        raise ValueError(f"scenario has no {path!r}")
    d[keys[-1]] = value


def _spread_centre(spread: Any) -> float:
    if isinstance(spread, dict) and "Uniform" in spread:
        return 0.5 * (spread["Uniform"]["min"] + spread["Uniform"]["max"])
    if isinstance(spread, dict) and "Normal" in spread:
        return spread["Normal"]["mean"]
    if isinstance(spread, dict) and "Fixed" in spread:
        return spread["Fixed"]
    raise ValueError(f"unexpected distribution {spread!r}")


def _tle_checksum(line: str) -> str:
    total = sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68])
    return line[:68] + str(total % 10)


def _sun_right_ascension_deg(epoch_utc: str) -> float:
    """The Sun's right ascension (low-precision almanac formula, about 0.01 deg), for the
    node of a local time."""
    t = datetime.datetime.fromisoformat(epoch_utc.replace("Z", "+00:00"))
    jd = t.timestamp() / 86400.0 + 2440587.5
    n = jd - 2451545.0
    mean_long = (280.460 + 0.9856474 * n) % 360.0
    g = math.radians((357.528 + 0.9856003 * n) % 360.0)
    ecl_long = math.radians(mean_long + 1.915 * math.sin(g) + 0.020 * math.sin(2 * g))
    obliquity = math.radians(23.439 - 0.0000004 * n)
    ra = math.atan2(math.cos(obliquity) * math.sin(ecl_long), math.cos(ecl_long))
    return math.degrees(ra) % 360.0


def _orbit(scenario: dict, altitude_km=None, inclination_deg=None, local_time_h=None) -> None:
    tle = scenario["orbit"]["Tle"]
    line2 = tle["line2"]
    incl = float(line2[8:16])
    raan = float(line2[17:25])
    ecc = float("0." + line2[26:33].strip())
    mean_motion = float(line2[52:63])
    if inclination_deg is not None:
        if not 0.0 <= inclination_deg <= 180.0:
            raise ValueError(f"inclination_deg {inclination_deg}: outside 0..180")
        incl = inclination_deg
    if altitude_km is not None:
        a_km = _R_EARTH_KM + altitude_km
        if a_km * (1.0 - ecc) - _R_EARTH_KM < 150.0:
            raise ValueError(f"altitude_km {altitude_km}: perigee below 150 km")
        mean_motion = math.sqrt(_MU_EARTH_KM3_S2 / a_km**3) * 86400.0 / (2 * math.pi)
    if local_time_h is not None:
        raan = (_sun_right_ascension_deg(scenario["epoch_utc"]) + 15.0 * (local_time_h - 12.0)) % 360.0
    new = (
        line2[:8]
        + f"{incl:8.4f}"
        + line2[16:17]
        + f"{raan:8.4f}"
        + line2[25:52]
        + f"{mean_motion:11.8f}"
        + line2[63:68]
    )
    tle["line2"] = _tle_checksum(new)


def _albedo_map(scenario: dict, name: str) -> None:
    effects = [e for e in scenario.get("effects", []) if not (isinstance(e, dict) and "Albedo" in e)]
    if name != "none":
        effects.insert(0, {"Albedo": {"map": name}})
    scenario["effects"] = effects


def _mounting(s, v):
    s["photodiodes"]["mounting_error_deg"] = {"Uniform": {"min": -v, "max": v}}


def _scale_spread(s, v):
    c = _spread_centre(s["photodiodes"]["scale_V"])
    s["photodiodes"]["scale_V"] = {"Uniform": {"min": c * (1 - v / 100), "max": c * (1 + v / 100)}}


def _tumble(s, v):
    s["spacecraft"]["initial_rate"] = {"RandomTumble": {"magnitude_rad_s": v * _DEG}}


def _gyro_bias(s, v):
    s["gyro"]["bias_rad_s"] = {"Uniform": {"min": -v * _DEG, "max": v * _DEG}}


def _set(path):
    return lambda s, v: _set_path(s, path, float(v))


# What each named dispersion (or override) does to the scenario dict; `scenario.<path>`
# sets any field of it. The run's `cut` and `sets` are not scenario fields.
DISPERSIONS: dict = {
    "mounting_error_max_deg": _mounting,
    "scale_spread_percent": _scale_spread,
    "photodiode_noise_V": _set("photodiodes.noise_V"),
    "gyro_noise_rad_s": _set("gyro.noise_rad_s"),
    "magnetometer_noise_nT": _set("magnetometer.noise_nT"),
    "tumble_rate_deg_s": _tumble,
    "gyro_bias_max_deg_s": _gyro_bias,
    "altitude_km": lambda s, v: _orbit(s, altitude_km=float(v)),
    "inclination_deg": lambda s, v: _orbit(s, inclination_deg=float(v)),
    "local_time_h": lambda s, v: _orbit(s, local_time_h=float(v)),
    "albedo_map": lambda s, v: _albedo_map(s, str(v)),
    "duration_s": _set("duration_s"),
    "pass_on_s": None,
    "pass_period_s": None,
    "sets": None,
}


def _apply(scenario: dict, values: dict) -> None:
    # Orbit elements together, so that the order of the keys does not matter.
    orbit = {k: float(values[k]) for k in ("altitude_km", "inclination_deg", "local_time_h") if k in values}
    for name, value in values.items():
        if name in orbit or DISPERSIONS.get(name, 0) is None:
            continue
        if name.startswith("scenario."):
            _set_path(scenario, name[len("scenario."):], value)
        elif name in DISPERSIONS:
            DISPERSIONS[name](scenario, value)
        else:
            raise ValueError(f"unknown override {name!r}")
    if orbit:
        _orbit(scenario, **orbit)


def scenario_for(spec: dict, params: dict) -> dict:
    """The scenario dict of a run: the base, its overrides, then the drawn ``params``."""
    from . import scenario as load_scenario

    base = spec["scenario"]
    scenario = copy.deepcopy(base) if isinstance(base, dict) else load_scenario(base)
    _apply(scenario, spec["overrides"])
    _apply(scenario, params)
    return scenario


def _run_options(spec: dict, params: dict) -> tuple:
    values = {**spec["overrides"], **params}
    cut = spec["cut"]
    if "pass_on_s" in values or "pass_period_s" in values:
        on = float(values.get("pass_on_s", 300.0))
        period = float(values.get("pass_period_s", 900.0))
        cut = f"passes:{on}/{period}"
    sets = int(values.get("sets", spec["sets"]))
    return cut, sets


def _flatten(result: dict) -> dict:
    rotation = result.get("normals_rotation")
    row = {
        "worst_normal_deg": result["worst_normal_deg"],
        "worst_scale_percent": result["worst_scale_percent"],
        "attitude_rms_deg": result["attitude_rms_deg"],
        "attitude_settled_rms_deg": result["attitude_settled_rms_deg"],
        "segments": int(result["segments"][0]),
        "segments_lost": int(result["segments"][1]),
        "first_lost_row": None if result["first_lost"] is None else int(result["first_lost"][0]),
        "first_lost": None if result["first_lost"] is None else result["first_lost"][1],
        "best_single_normal_deg": None if result["best_single"] is None else result["best_single"][0],
        "best_single_scale_percent": None if result["best_single"] is None else result["best_single"][1],
        "final_inside": int(result["final_inside"][0]),
        "final_states": int(result["final_inside"][1]),
        "residual_inside": result["residual_inside"],
        "magnitude_mean": result["magnitude"][0],
        "magnitude_std": result["magnitude"][1],
        "converged": result["converged"],
        "runtime_s": result["runtime_s"],
        "verdict": result["verdict"],
        "calibrated_states": int(result["by_status"]["calibrated"]),
        "calibrated_outside_3sigma": int(result["by_status"]["calibrated_outside_3sigma"]),
        "weakly_determined_states": int(result["by_status"]["weakly_determined"]),
        "weakly_determined_outside_3sigma": int(
            result["by_status"]["weakly_determined_outside_3sigma"]
        ),
        "not_determined_states": int(result["by_status"]["not_determined"]),
        "not_determined_outside_3sigma": int(result["by_status"]["not_determined_outside_3sigma"]),
        "attitude_about_sun_inside": result["attitude_about_sun_inside"],
        "attitude_across_sun_inside": result["attitude_across_sun_inside"],
        # The same for the smoother's attitude (estimates_smoothed.csv).
        "smoothed_attitude_about_sun_inside": result["smoothed_attitude_sun_inside"][0],
        "smoothed_attitude_across_sun_inside": result["smoothed_attitude_sun_inside"][1],
        # Running gyro-bias errors inside their 3 sigma, per axis.
        "gyro_bias_inside": result["gyro_bias_inside"],
        # With several sets: the repeatability verdict, the parameters whose sets differ
        # (joined by ";"), the gyro-bias change warnings, and the single tests beyond 3
        # sigma, their count and the RMS of their z.
        "repeatability": result["repeatability"],
        "repeat_differing": ";".join(result["differing"]),
        "bias_change_warnings": int(result["bias_change_warnings"]),
        "repeat_tests_beyond_3": int(result["repeat_tests_beyond_3"][0]),
        "repeat_tests": int(result["repeat_tests_beyond_3"][1]),
        "repeat_rms_z": float(result["repeat_tests_beyond_3"][2]),
        # Sun-only acquisitions probed for the half turn about the Sun line, those that
        # kept it, and those the data did not decide.
        "about_sun_probes": int(result["about_sun_probes"][0]),
        "about_sun_turned": int(result["about_sun_probes"][1]),
        "about_sun_undecided": int(result["about_sun_probes"][2]),
        # Whether the rigid-body dynamics carried the attitude between samples, and the
        # chi-square per degree of freedom of the gyro's rate test (None when not run).
        "dynamics": bool(result["dynamics"][0]),
        "gyro_rate_chi_square_per_dof": result["dynamics"][1],
        # The one rotation from the nominal to the calibrated normals (summary.json
        # normals_rotation): its angle, its chi-square, the part of the normals' changes it
        # explains, and whether it is a finding; None when it was not fitted.
        "normals_rotation_deg": None if rotation is None else rotation["angle_deg"],
        "normals_rotation_chi_square": None if rotation is None else rotation["chi_square"],
        "normals_rotation_explained": None if rotation is None else rotation["explained"],
        "normals_turned": None if rotation is None else bool(rotation["finding"]),
        # The summary's warning of the mounting: a turned head found, or one the data could
        # not check; None when the run says nothing of it.
        "mounting_warning": result["mounting_warning"],
        # The factor every reported sigma was multiplied by (summary.json dispersion).
        "sigma_factor": result["sigma_factor"],
    }
    for pd in result["photodiodes"]:
        p = f"pd{pd['index']:02d}"
        row[f"{p}_normal_error_deg"] = pd["normal_error_deg"]
        row[f"{p}_scale_error_percent"] = pd["scale_error_percent"]
        row[f"{p}_scale_error_V"] = pd["scale_error_V"]
        row[f"{p}_lit_minutes"] = pd["lit_minutes"]
    return row


def _worker_name() -> Optional[str]:
    try:
        from distributed import get_worker

        return get_worker().address
    except Exception:
        return None


def _write_json(path: pathlib.Path, value: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    _atomic_bytes(path, json.dumps(value, indent=2, default=str).encode())


def run_task(spec: dict, task: dict, out_dir: Optional[str] = None) -> dict:
    """Runs one task of a campaign (on a worker) and returns its record; a failure is
    recorded with its error, never raised."""
    import pdcal

    started = time.time()
    record: dict = {"run_id": task["run_id"]}
    try:
        if "fleet" in spec:
            record["dataset"] = task["dataset"]
            record.update(_fleet_run(spec, task, out_dir))
        else:
            seed = task["seed"]
            record["seed"] = seed
            params = draw(spec, seed)
            record.update({f"param_{k}": v for k, v in params.items()})
            scenario = scenario_for(spec, params)
            cut, sets = _run_options(spec, params)
            result = pdcal._pdcal.sim_calibrate(
                scenario,
                seed=seed,
                config=spec["config"],
                photodiode_only=bool(spec["photodiode_only"]),
                cut=cut,
                sets=sets,
            )
            record.update(_flatten(result))
            if spec["diagnose"]:
                dataset = pdcal.simulate(scenario, seed=seed)
                record["diagnosis_verdict"] = pdcal.diagnose(dataset).verdict
            if spec["keep_runs"] and out_dir is not None:
                run_dir = pathlib.Path(out_dir) / "runs" / task["run_id"]
                _write_json(
                    run_dir / "run.json",
                    {
                        "seed": seed,
                        "params": params,
                        "cut": cut,
                        "sets": sets,
                        "config": spec["config"],
                        "photodiode_only": spec["photodiode_only"],
                        "scenario": scenario,
                    },
                )
                _write_json(run_dir / "result.json", result)
        record["status"] = "ok"
        record["error"] = None
    except Exception as e:  # a failing run is a row of the table, not the campaign's end
        record["status"] = "failed"
        record["error"] = f"{type(e).__name__}: {e}"
        record["traceback"] = traceback.format_exc(limit=4)
    record["wall_s"] = time.time() - started
    record["worker"] = _worker_name()
    return record


def _fleet_run(spec: dict, task: dict, out_dir: Optional[str]) -> dict:
    import pdcal

    dataset = pdcal.Dataset.read(task["dataset"])
    calibration = pdcal.calibrate(dataset, config=spec["config"], smoother=bool(spec["smoother"]))
    if out_dir is not None:
        target = pathlib.Path(out_dir) / "runs" / task["run_id"]
        target.parent.mkdir(parents=True, exist_ok=True)
        # Replaces an earlier pdcal output there (a run in flight when a campaign was
        # interrupted), never other files (Calibration.write's rule).
        calibration.write(target)
    summary_json = calibration.summary
    row: dict = {"runtime_s": summary_json.get("runtime_s")}
    for key in ("residuals",):
        res = summary_json.get(key) or {}
        if "fraction_within_3sigma" in res:
            row["residual_inside"] = res["fraction_within_3sigma"]
    mag = ((summary_json.get("sun_vector_magnitude") or {}).get("calibrated")) or {}
    if "mean" in mag:
        row["magnitude_mean"] = mag["mean"]
        row["magnitude_std"] = mag["std"]
    if dataset.truth is not None:
        ev = pdcal.evaluate(dataset, calibration)
        row["worst_normal_deg"] = ev["worst_normal_error_deg"]
        row["worst_scale_percent"] = ev["worst_scale_error_percent"]
        row["attitude_rms_deg"] = ev["attitude"]["rms_deg"]
        row["attitude_settled_rms_deg"] = ev["attitude_after_acquisition"]["rms_deg"]
        for pd in ev["photodiodes"]:
            p = f"pd{pd['index']:02d}"
            row[f"{p}_normal_error_deg"] = pd["normal_error_deg"]
            row[f"{p}_scale_error_percent"] = pd["scale_error_percent"]
    for i, (c, az, el) in enumerate(
        zip(calibration.scale_V, calibration.azimuth_deg, calibration.elevation_deg)
    ):
        p = f"pd{i + 1:02d}"
        row[f"{p}_scale_V"] = float(c)
        row[f"{p}_azimuth_deg"] = float(az)
        row[f"{p}_elevation_deg"] = float(el)
    if spec["diagnose"]:
        row["diagnosis_verdict"] = pdcal.diagnose(dataset).verdict
    return row


# ---------------------------------------------------------------- the table


def _atomic_bytes(path: pathlib.Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix="." + path.name + ".", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _order(records: Iterable[dict], spec: dict):
    import pandas as pd

    order = {t["run_id"]: i for i, t in enumerate(tasks(spec))}
    df = pd.DataFrame(list(records))
    if df.empty:
        return df
    df = df.assign(_k=df["run_id"].map(order)).sort_values("_k").drop(columns="_k")
    first = ["run_id", "seed", "dataset", "status", "error"]
    params = sorted(c for c in df.columns if c.startswith("param_"))
    figures = [c for c in FIGURES if c in df.columns]
    pds = sorted(c for c in df.columns if c.startswith("pd"))
    lead = [c for c in first if c in df.columns] + params + figures + pds
    rest = [c for c in df.columns if c not in lead]
    return df[lead + rest].reset_index(drop=True)


def write_table(df, out_dir: pathlib.Path) -> None:
    """results.parquet and results.csv beside it, each replaced whole (a reader sees the
    old table or the new one, never part of one)."""
    import io

    buf = io.BytesIO()
    df.to_parquet(buf, index=False)
    _atomic_bytes(out_dir / TABLE, buf.getvalue())
    _atomic_bytes(out_dir / CSV, df.to_csv(index=False).encode())


class _Writer:
    """Rewrites the table after a finished run unless the last rewrite was recent: at most
    a sixth of the time goes to rewriting (a 1000-row table takes some 0.4 s), so a small
    table is written after every run and a large one every few runs; `flush` writes what
    is pending."""

    def __init__(self, write: Callable[[], None]):
        self.write = write
        self.pending = False
        self.last_end = -math.inf
        self.last_cost = 0.0

    def finished(self) -> None:
        self.pending = True
        if time.perf_counter() - self.last_end >= 5.0 * self.last_cost:
            self.flush()

    def flush(self) -> None:
        if self.pending:
            start = time.perf_counter()
            self.write()
            self.last_end = time.perf_counter()
            self.last_cost = self.last_end - start
            self.pending = False


def read_table(out_dir) -> "Any":
    """The results table of a campaign directory (a pandas DataFrame)."""
    import pandas as pd

    return pd.read_parquet(pathlib.Path(out_dir) / TABLE)


def _spec_json(spec: dict) -> str:
    return json.dumps(spec, sort_keys=True, indent=2)


# ---------------------------------------------------------------- running on Dask


def _client(client, workers: Optional[int]):
    """(client, what to close at the end: the client and cluster made here)."""
    from distributed import Client, LocalCluster

    if client is None:
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None
        )
        made = Client(cluster)
        return made, [made, cluster]
    if isinstance(client, str):
        made = Client(client)
        return made, [made]
    return client, []


def run(
    campaign: Any,
    out_dir,
    client=None,
    *,
    workers: Optional[int] = None,
    progress: Optional[Callable[[int, int, int], None]] = None,
    retry_failed: bool = False,
):
    """Runs a campaign into ``out_dir`` and returns its results table (pandas DataFrame).

    ``campaign``: a dict or a ``.ron``/``.json`` path (``docs/campaign.md``). ``client``:
    None (an in-process ``LocalCluster`` of ``workers`` processes, by default one per core),
    a ``dask.distributed.Client``, or a scheduler address. Runs already in
    ``out_dir/results.parquet`` are skipped (failed ones too unless ``retry_failed``); the
    table is rewritten as runs finish (docs/campaign.md: Faults and resuming). ``progress(done, total, failed)`` is
    called as runs finish. The summary (index.html, summary.md) is written at the end.
    """
    import pandas as pd
    from distributed import as_completed

    spec = load(campaign)
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec_file = out / SPEC
    if spec_file.exists():
        if json.loads(spec_file.read_text()) != json.loads(_spec_json(spec)):
            raise ValueError(
                f"{spec_file}: {out} holds another campaign; resume with the same "
                "description or choose another directory"
            )
    else:
        _atomic_bytes(spec_file, _spec_json(spec).encode())

    all_tasks = tasks(spec)
    records: dict = {}
    if (out / TABLE).exists():
        for row in read_table(out).to_dict("records"):
            row = {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}
            if row["status"] == "ok" or not retry_failed:
                records[row["run_id"]] = row
    todo = [t for t in all_tasks if t["run_id"] not in records]
    failed = sum(1 for r in records.values() if r["status"] != "ok")
    if progress:
        progress(len(records), len(all_tasks), failed)

    if todo:
        writer = _Writer(lambda: write_table(_order(records.values(), spec), out))
        dask_client, owned = _client(client, workers)
        futures = []
        try:
            # Keys name the campaign directory too, so two campaigns on one scheduler never
            # share a result.
            tag = zlib.crc32((str(out.resolve()) + _spec_json(spec)).encode())
            futures = [
                dask_client.submit(
                    run_task, spec, t, str(out.resolve()), key=f"pdcal-{tag:08x}-{t['run_id']}", pure=False
                )
                for t in todo
            ]
            by_key = {f.key: t for f, t in zip(futures, todo)}
            for future in as_completed(futures):
                try:
                    record = future.result()
                except Exception as e:  # the scheduler gave up on it (a worker died each time)
                    t = by_key[future.key]
                    record = {
                        "run_id": t["run_id"],
                        **({"seed": t["seed"]} if "seed" in t else {"dataset": t["dataset"]}),
                        "status": "failed",
                        "error": f"{type(e).__name__}: {e}",
                    }
                records[record["run_id"]] = record
                if record["status"] != "ok":
                    failed += 1
                writer.finished()
                if progress:
                    progress(len(records), len(all_tasks), failed)
                future.release()
            writer.flush()
        except BaseException:
            # Interrupted: the finished runs are written, the runs in flight are lost, and
            # none stays queued on a shared cluster.
            dask_client.cancel(futures)
            writer.flush()
            raise
        finally:
            for thing in owned:
                thing.close()
    df = _order(records.values(), spec)
    if not todo and not (out / TABLE).exists():
        write_table(df, out)
    summary(df, spec, out)
    return df


# ---------------------------------------------------------------- the summary

# The accuracy table of docs/validation.md: (column, label, bound).
ACCURACY = [
    ("worst_normal_deg", "normal error, worst photodiode lit >= 5 min (deg)", "<= 0.5"),
    ("worst_scale_percent", "scale error, worst photodiode lit >= 5 min (%)", "<= 1"),
    ("attitude_rms_deg", "attitude error RMS, sunlit after 10 min (deg)", "<= 0.5"),
    ("attitude_settled_rms_deg", "attitude error RMS, sunlit from 60 s after each acquisition (deg)", "<= 1"),
    ("segments", "segments per run", "-"),
    ("segments_lost", "segments ending with the attitude lost", "-"),
    ("final_inside_fraction", "final calibration states inside 3-sigma (fraction)", "0.997 +- 0.005"),
    ("residual_inside", "photodiode residuals inside 3-sigma (fraction)", ">= 0.95"),
    ("magnitude_mean", "calibrated sun-vector magnitude mean", "0.99 .. 1.01"),
    ("magnitude_std", "calibrated sun-vector magnitude std", "<= 0.02"),
    ("converged", "estimates within 3-sigma of final after 10 sunlit min (fraction)", "all"),
    ("runtime_s", "filter run time (s)", "-"),
]
# Where the worst is the smallest value.
_LOW_IS_WORSE = {"final_inside_fraction", "residual_inside", "converged"}


def accuracy_table(df) -> str:
    """The accuracy table (Markdown) over the successful runs: mean, median, 90th and 99th
    percentiles and worst of each figure of merit."""
    ok = df[df["status"] == "ok"].copy() if "status" in df else df.copy()
    if "final_inside" in ok and "final_states" in ok:
        ok["final_inside_fraction"] = ok["final_inside"] / ok["final_states"].clip(lower=1)
    lines = [
        f"runs: {len(df)}, ok: {len(ok)}, failed: {len(df) - len(ok)}",
        "",
        "| figure of merit | mean | p50 | p90 | p99 | worst | bound |",
        "|---|---|---|---|---|---|---|",
    ]
    for col, label, bound in ACCURACY:
        if col not in ok or ok[col].dropna().empty:
            continue
        v = ok[col].dropna().astype(float).to_numpy()
        low = col in _LOW_IS_WORSE
        q = (lambda p: np.percentile(v, 100 - p)) if low else (lambda p: np.percentile(v, p))
        worst = v.min() if low else v.max()
        lines.append(
            f"| {label} | {v.mean():.4g} | {q(50):.4g} | {q(90):.4g} | {q(99):.4g} | {worst:.4g} | {bound} |"
        )
    return "\n".join(lines) + "\n"


def _figures(df, spec, out: pathlib.Path) -> list:
    params = [c for c in df.columns if c.startswith("param_")]
    if not params or "worst_normal_deg" not in df:
        return []
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    ok = df[df["status"] == "ok"]
    fig_dir = out / "figures"
    fig_dir.mkdir(exist_ok=True)
    made = []
    for p in params:
        name = p[len("param_"):]
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
        for ax, (col, label, bound) in zip(
            axes,
            [
                ("worst_normal_deg", "worst normal error (deg)", 0.5),
                ("worst_scale_percent", "worst scale error (%)", 1.0),
            ],
        ):
            x = ok[p]
            y = ok[col].astype(float)
            if x.dtype == object:
                cats = sorted(set(map(str, x)))
                pos = {c: i for i, c in enumerate(cats)}
                xs = np.array([pos[str(v)] for v in x], dtype=float)
                jitter = np.random.default_rng(0).uniform(-0.15, 0.15, len(xs))
                ax.plot(xs + jitter, y, ".", alpha=0.5, ms=4)
                ax.set_xticks(range(len(cats)), cats)
            else:
                x = x.astype(float)
                ax.plot(x, y, ".", alpha=0.5, ms=4)
                if len(x) >= 20:
                    edges = np.quantile(x, np.linspace(0, 1, 11))
                    mids, p90 = [], []
                    for lo, hi in zip(edges[:-1], edges[1:]):
                        sel = y[(x >= lo) & (x <= hi)]
                        if len(sel):
                            mids.append(0.5 * (lo + hi))
                            p90.append(np.percentile(sel, 90))
                    ax.plot(mids, p90, "-", color="C3", label="90th percentile per decile")
                    ax.legend(fontsize=8)
            law = spec.get("dispersions", {}).get(name, {})
            if "log_uniform" in law:
                ax.set_xscale("log")
            ax.axhline(bound, color="k", lw=0.8, ls="--")
            ax.set_xlabel(name)
            ax.set_ylabel(label)
            ax.set_yscale("log")
            ax.grid(alpha=0.3)
        failed = df[df["status"] != "ok"]
        fig.suptitle(f"{spec.get('name', 'campaign')}: {name} ({len(ok)} runs" + (f", {len(failed)} failed)" if len(failed) else ")"))
        fig.tight_layout()
        path = fig_dir / f"{name}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        made.append(path.relative_to(out))
    return made


def summary(df, spec: dict, out_dir) -> pathlib.Path:
    """Writes summary.md (the accuracy table) and index.html (the table, the figures of
    merit against each dispersed parameter, the failed runs) into ``out_dir``."""
    out = pathlib.Path(out_dir)
    table = accuracy_table(df) if len(df) else "no runs\n"
    _atomic_bytes(out / SUMMARY_MD, table.encode())
    figures = _figures(df, spec, out) if len(df) else []
    rows = []
    for line in table.splitlines():
        if line.startswith("|---"):
            continue
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            tag = "th" if not rows else "td"
            rows.append("<tr>" + "".join(f"<{tag}>{html.escape(c)}</{tag}>" for c in cells) + "</tr>")
    failed = df[df["status"] != "ok"] if len(df) else df
    fail_rows = "".join(
        f"<tr><td>{html.escape(str(r['run_id']))}</td><td>{html.escape(str(r.get('error')))}</td></tr>"
        for r in failed.to_dict("records")
    )
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>{html.escape(str(spec.get('name')))}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}
td:first-child,th:first-child{{text-align:left}}</style></head><body>
<h1>{html.escape(str(spec.get('name')))}</h1>
<p>{html.escape(table.splitlines()[0])}. Table: <a href="{TABLE}">{TABLE}</a>,
<a href="{CSV}">{CSV}</a>; description: <a href="{SPEC}">{SPEC}</a>.</p>
<h2>Accuracy over runs</h2><table>{''.join(rows)}</table>
{''.join(f'<h2>{html.escape(f.stem)}</h2><img src="{f.as_posix()}" alt="{html.escape(f.stem)}">' for f in figures)}
{f'<h2>Failed runs</h2><table><tr><th>run</th><th>error</th></tr>{fail_rows}</table>' if fail_rows else ''}
</body></html>
"""
    path = out / INDEX
    _atomic_bytes(path, page.encode())
    return path


# ---------------------------------------------------------------- command line


class _Bar:
    def __init__(self, stream=sys.stderr):
        self.stream = stream
        self.start = time.time()

    def __call__(self, done: int, total: int, failed: int) -> None:
        width = 40
        filled = int(width * done / max(total, 1))
        elapsed = time.time() - self.start
        eta = ""
        if 0 < done < total:
            eta = f", eta {_hms(elapsed / done * (total - done))}"
        text = (
            f"\r[{'#' * filled}{' ' * (width - filled)}] {done}/{total} runs"
            f"{f', {failed} failed' if failed else ''}, {_hms(elapsed)} elapsed{eta}"
        )
        self.stream.write(text)
        if done == total:
            self.stream.write("\n")
        self.stream.flush()


def _hms(s: float) -> str:
    s = int(s)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m pdcal.campaign",
        description="Runs a pdcal campaign (a design study or a fleet) on Dask.",
    )
    parser.add_argument("spec", help="the campaign description (.ron or .json)")
    parser.add_argument("--out", required=True, help="output directory (resumed if present)")
    parser.add_argument("--scheduler", help="a Dask scheduler address (default: a local cluster)")
    parser.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    parser.add_argument("--retry-failed", action="store_true", help="run failed runs again")
    args = parser.parse_args(argv)
    try:
        df = run(
            args.spec,
            args.out,
            client=args.scheduler,
            workers=args.workers,
            progress=_Bar(),
            retry_failed=args.retry_failed,
        )
    except (ValueError, OSError) as e:
        print(f"pdcal.campaign: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\npdcal.campaign: interrupted; run again to resume", file=sys.stderr)
        return 130
    failed = int((df["status"] != "ok").sum()) if len(df) else 0
    print(accuracy_table(df), end="")
    print(f"written to {args.out}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

"""pdcal: on-orbit calibration of spacecraft photodiodes (coarse sun sensors).

The functions and classes are the Rust library's (the native module ``pdcal._pdcal``);
pure-Python helpers such as ``pdcal.basilisk`` live beside it in this package.
"""

from ._pdcal import (
    Calibration,
    Dataset,
    Diagnosis,
    MagCalibration,
    __version__,
    calibrate,
    diagnose,
    evaluate,
    export_onboard,
    magcal,
    scenario,
    simulate,
    sun_vector,
)

__all__ = [
    "Calibration",
    "Dataset",
    "Diagnosis",
    "MagCalibration",
    "__version__",
    "calibrate",
    "diagnose",
    "evaluate",
    "export_onboard",
    "magcal",
    "scenario",
    "simulate",
    "sun_vector",
]

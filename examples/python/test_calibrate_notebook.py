"""The notebook example runs from start to end and calibrates within its own bounds."""

import os
import pathlib
import runpy

import numpy as np


def test_the_notebook_runs(tmp_path):
    here = pathlib.Path(__file__).parent
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        names = runpy.run_path(str(here / "calibrate_notebook.py"))
    finally:
        os.chdir(cwd)
    assert np.median(np.abs(names["scale_error_percent"])) < 5.0
    assert names["evaluation"]["photodiodes"]

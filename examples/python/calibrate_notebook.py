# %% [markdown]
# # Calibrating photodiodes from Python
#
# Simulate a short stretch of the RAX-2-like scenario, calibrate it, compare the
# estimates with the simulated truth and plot how the scale factors settle. Runs as a
# plain script (`python examples/python/calibrate_notebook.py`), cell by cell in an editor
# that knows `# %%`, and in CI (`test_calibrate_notebook.py`). Plots need matplotlib;
# without it they are skipped.

# %%
import numpy as np

import pdcal

scenario = pdcal.scenario("rax2-like")
scenario["duration_s"] = 3000.0  # 50 minutes (the first 24 in eclipse) keep it quick
dataset = pdcal.simulate(scenario, seed=7)
print(dataset)

# %% [markdown]
# The arrays are numpy; a blank (not sampled) cell is NaN.

# %%
print("rows:", dataset.rows, "photodiodes:", dataset.photodiodes_V.shape[1])
print("sunlit fraction:", float(np.mean(dataset.truth["eclipse"] > 0.99)))

# %%
calibration = pdcal.calibrate(dataset)
truth = dataset.truth
scale_error_percent = 100.0 * (calibration.scale_V - truth["scale_V"]) / truth["scale_V"]
elevation_error_deg = calibration.elevation_deg - truth["elevation_deg"]
for i, (ds, de) in enumerate(zip(scale_error_percent, elevation_error_deg), start=1):
    print(f"pd{i:02d}: scale {ds:+6.2f} %  elevation {de:+6.2f} deg")

# %%
evaluation = pdcal.evaluate(dataset, calibration)
print("worst normal error, deg:", evaluation["worst_normal_error_deg"])

# %%
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    plt = None
    print("matplotlib is not installed: no plots")

if plt is not None:
    est = calibration.estimates_smoothed
    fig, ax = plt.subplots(figsize=(8, 4))
    for i in range(1, 5):
        ax.plot(est["t_s"] / 60.0, est[f"pd{i:02d}_scale_V"], label=f"pd{i:02d}")
        ax.axhline(truth["scale_V"][i - 1], color=ax.lines[-1].get_color(), ls=":")
    ax.set_xlabel("time, min")
    ax.set_ylabel("scale factor at 1 AU, V")
    ax.legend()
    fig.savefig("calibrate_notebook_scales.png", dpi=80)
    plt.close(fig)

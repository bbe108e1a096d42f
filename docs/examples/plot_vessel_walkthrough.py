"""
Your own vessel, executed: REMUS 100 from tracks to a diagnosis
===============================================================

The walkthrough of :doc:`../vessel` ("From tracks to a model, a prediction and a diagnosis"), run
at every build of these pages: each command below is the one on that page, and each output is
what it printed on this build. The vehicle file is the packaged ``remus100``
(``bayesid/vehicles/remus100.toml``: Prestero 2001, converted in :doc:`plot_remus100`), whose ``Yvabsv`` is the thesis' printed value divided by ten.
The stand-in tracks are simulated with the *printed* value, so the file is wrong by a factor of
ten in one coefficient, and noise is added to what a navigation suite would log
(``docs/walkthrough/make_logs.py``).

The end of the page compares the fitted models pooled and window by window: a pooled RMS can
rank two models the wrong way round when a few windows go astray. A statement the guide page makes in words is checked here (``as the
guide says``): the build fails when a run contradicts it. Each ``bayesid`` command runs as
``python -m bayesid.cli``, the same command; progress bars are left out of the outputs.
"""

import json
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import bayesid

here = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd()  # the gallery runs in docs/examples
work = Path(tempfile.mkdtemp(prefix="bayesid_walkthrough_"))  # a fresh folder: the commands run in it
shutil.copy(Path(bayesid.__file__).parent / "vehicles" / "remus100.toml", work)  # the packaged file
shutil.copy(here.parent / "walkthrough" / "make_logs.py", work)

package_root = str(Path(bayesid.__file__).parents[1])  # the commands run the bayesid these pages document
env = dict(os.environ, PYTHONPATH=os.pathsep.join([package_root, os.environ.get("PYTHONPATH", "")]))
env.update(PYTHONUNBUFFERED="1", TQDM_DISABLE="1", MPLBACKEND="Agg")
PROGRESS = re.compile(r"\d+%\|")  # a tqdm frame


def run(command: str) -> None:
    """Print a command line as typed, run it here, print its output (stdout and stderr)."""
    args = shlex.split(command)
    shown = shlex.join(args)
    if len(shown) > 90:  # one option a line, as a shell script would break it
        shown = re.sub(r" (--\S+)", r" \\\n      \1", shown)
    print(f"$ {shown}")
    exe = [sys.executable, "-m", "bayesid.cli"] if args[0] == "bayesid" else [sys.executable]
    proc = subprocess.run([*exe, *args[1:]], cwd=work, env=env, capture_output=True, text=True, check=False)
    for line in (proc.stdout + proc.stderr).splitlines():  # stderr: progress bars, warnings, errors
        kept = [part for part in line.split("\r") if not PROGRESS.search(part)]
        if kept or not line:
            print("".join(kept))
    if proc.returncode != 0:
        raise RuntimeError(f"{command!r} exited with {proc.returncode}: the walkthrough no longer runs")


def claim(holds: bool, text: str) -> None:
    """A statement the guide page makes in words: the build fails when this run contradicts it."""
    if not holds:
        raise RuntimeError(f"docs/vessel.rst says that {text}, and this run contradicts it: update the page")
    print(f"as the guide says: {text}")


# %%
# 1. Tracks
# ---------
#
# The file with the printed ``Yvabsv`` (``sed 's/^Yvabsv = .*/Yvabsv = -1.438006e+00/'
# remus100.toml > remus100_as_printed.toml`` on the guide page), two 10-degree manoeuvres to fit
# on and two 15-degree ones held out, then the logs.

text = (work / "remus100.toml").read_text()
(work / "remus100_as_printed.toml").write_text(re.sub(r"(?m)^Yvabsv = .*$", "Yvabsv = -1.438006e+00", text))
(work / "sim").mkdir()
for a in (10, 15):
    run(
        f"bayesid simulate --vehicle remus100_as_printed.toml --manoeuvre zigzag --angle {a} --duration 120 --mode horizontal --out sim/zigzag_{a}.csv"
    )
run(
    "bayesid simulate --vehicle remus100_as_printed.toml --manoeuvre turn --angle 10 --duration 120 --mode horizontal --out sim/turn_10.csv"
)
run(
    "bayesid simulate --vehicle remus100_as_printed.toml --manoeuvre turn --angle -15 --duration 120 --mode horizontal --out sim/turn_-15.csv"
)
run("python make_logs.py")

# %%
# 2. Fit
# ------
#
# Eight coefficients free, among them ``Yvabsv``; every other keeps the file's value.

run(
    "bayesid fit --vehicle remus100.toml --train logs/zigzag_10.csv logs/turn_10.csv "
    "--free Yv,Yr,Nv,Nr,Ydr,Ndr,Yvabsv,Nrabsr --fit-window 5 --start fitted --dt 0.1 --out fit"
)


def prime(path: str, name: str) -> float:
    """A coefficient's prime value in a vehicle file."""
    return float(re.search(rf"(?m)^{name}\s*=\s*(\S+)", (work / path).read_text()).group(1))


model = json.loads((work / "fit/model.json").read_text())
est = dict(zip(model["param_names"], model["p"], strict=True))
sd = dict(zip(model["param_names"], model["sd"], strict=True))
print(f"{'coefficient':<11} {'file':>11} {'tracks made with':>17} {'identified':>11} {'sd':>9}")
for name in model["param_names"]:
    print(
        f"{name:<11} {prime('remus100.toml', name):11.4g} {prime('remus100_as_printed.toml', name):17.4g} "
        f"{est[name]:11.4g} {sd[name]:9.2g}"
    )
file_value, printed = prime("remus100.toml", "Yvabsv"), prime("remus100_as_printed.toml", "Yvabsv")
claim(
    abs(est["Yvabsv"] - printed) < abs(est["Yvabsv"] - file_value),
    "the fit moves Yvabsv from the file's value to near the printed one",
)

# %%
# Why ``--fit-window 5``: REMUS's linear sway-yaw dynamics are unstable, so an error in a window's
# start state grows quickly. At the true coefficients (a fit of ``Yvabsv`` alone on
# ``remus100_as_printed.toml``), the training error over longer windows:

train_rms = {}
for w in (5, 10, 30):
    run(
        f"bayesid fit --vehicle remus100_as_printed.toml --train logs/zigzag_10.csv logs/turn_10.csv "
        f"--free Yvabsv --fit-window {w} --start fitted --dt 0.1 --out true_w{w}"
    )
    train_rms[w] = json.loads((work / f"true_w{w}/model.json").read_text())["train_scores"]["rms_position_m"]
claim(train_rms[5] < train_rms[10] < train_rms[30], "at the true coefficients the error grows with the window")

# %%
# 3. Predict
# ----------

run(
    "bayesid predict --model fit/model.json --track logs/zigzag_15.csv logs/turn_-15.csv --score-window 5 --start fitted --out pred"
)
print((work / "pred/report.md").read_text())
pred = json.loads((work / "pred/predict.json").read_text())
median_window = statistics.median(w["rms_position_m"] for w in pred["windows"])
claim(
    pred["whole_run"]["pooled"]["rms_position_m"] > 2 * median_window,
    "one open-loop simulation of a whole run drifts further than the typical window",
)

# %%
# 4. Diagnose
# -----------

run(
    "bayesid diagnose --vehicle remus100.toml --train logs/zigzag_10.csv logs/turn_10.csv "
    "--heldout logs/zigzag_15.csv logs/turn_-15.csv --score-window 5 --dt 0.1 --start fitted "
    "--exclude crossflow --out diag"
)
diag = json.loads((work / "diag/diagnosis.json").read_text())
claim(diag["verdict"] == "none", "the verdict is none, although Yvabsv is ten times too small in the file")

# %%
# 5. Which model predicts better? Window by window
# -------------------------------------------------
#
# Three models on the same held-out windows, each scored by ``bayesid predict`` with the same
# protocol: the eight-coefficient fit of step 2; the six-coefficient fit the diagnosis starts from
# (``Yvabsv`` kept at the file's wrong value: ``bayesid fit`` with the free set diagnose uses for a
# submarine), and the true coefficients (the ``--fit-window 5`` fit of ``Yvabsv`` alone above).

run(
    "bayesid fit --vehicle remus100.toml --train logs/zigzag_10.csv logs/turn_10.csv "
    "--free Yv,Yr,Nv,Nr,Ydr,Ndr --fit-window 5 --start fitted --dt 0.1 --out fit6"
)
run(
    "bayesid predict --model fit6/model.json --track logs/zigzag_15.csv logs/turn_-15.csv --score-window 5 --start fitted --out pred6"
)
run(
    "bayesid predict --model true_w5/model.json --track logs/zigzag_15.csv logs/turn_-15.csv --score-window 5 --start fitted --out pred_true"
)

# %%
# Every held-out window's RMS position error (``windows`` in ``predict.json``), the pooled RMS
# (over all samples) and the median over the windows:

label = {"pred": "8 free (fit)", "pred6": "6 free (diagnosis base)", "pred_true": "true coefficients"}
res = {k: json.loads((work / f"{k}/predict.json").read_text()) for k in label}
win = {k: r["windows"] for k, r in res.items()}
keys = [(w["track"], w["t_start"]) for w in win["pred"]]
for k in label:
    assert [(w["track"], w["t_start"]) for w in win[k]] == keys  # the same windows
err = {k: np.array([w["rms_position_m"] for w in win[k]]) for k in label}
for k, name in label.items():
    print(f"{name:<24} pooled {res[k]['pooled']['rms_position_m']:.3f} m, median window {np.median(err[k]):.3f} m")
n = len(keys)
better = err["pred"] < err["pred6"]
print(f"\nthe 8-coefficient fit beats the 6-coefficient one in {better.sum()} of {n} windows; where it does not:")
for i in np.flatnonzero(~better):
    w8, w6 = win["pred"][i], win["pred6"][i]
    print(
        f"  {w8['track']} from {w8['t_start']:.0f} s: {w8['rms_position_m']:.3f} m against {w6['rms_position_m']:.3f} m "
        f"(heading RMS {w8['rms_heading_deg']:.1f} deg against {w6['rms_heading_deg']:.1f} deg)"
    )
true_better = err["pred_true"] < err["pred6"]
print(f"the true coefficients beat the 6-coefficient fit in {true_better.sum()} of {n} windows")
pooled = {k: r["pooled"]["rms_position_m"] for k, r in res.items()}
claim(
    pooled["pred6"] > max(pooled["pred"], pooled["pred_true"]),
    "held out, the models with the right Yvabsv predict better than this six-coefficient model, pooled",
)
claim(
    better.sum() > n / 2 and true_better.sum() > n / 2,
    "held out, the models with the right Yvabsv predict better than this six-coefficient model, window by window",
)
claim((~better).sum() <= n / 10, "the eight-coefficient fit loses only a few windows")

fig, ax = plt.subplots(figsize=(8, 3.6))
x = np.arange(n)
for k, style in zip(label, ("o", "s", "^"), strict=True):
    ax.semilogy(x, err[k], style, ms=4, mfc="none", label=label[k])
ax.axvline(sum(t == keys[0][0] for t, _ in keys) - 0.5, color="0.6", lw=0.8)
ax.set_xticks(x[::4], [f"{t}\n{s:.0f} s" for t, s in keys[::4]], fontsize=7)
ax.set_ylabel("RMS position error (m)")
ax.set_title("held-out 5 s windows", fontsize=9)
ax.legend(fontsize=8)
fig.tight_layout()

# %%
# The pooled RMS is a mean of squares: a few windows in which a simulation goes astray from its
# start can weigh more than all the others together. Compare models window by window (or by the
# median and the worst windows) as well as by a pooled number, and read a
# diagnosis verdict together with the fit: ``none`` says that the model needs no further effect
# to predict these windows within the noise, not that the coefficients it holds fixed are right.

shutil.rmtree(work, ignore_errors=True)

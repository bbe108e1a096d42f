"""
Ship tutorial: the HSVA KVLCC2 runs, from raw files to a diagnosis
==================================================================

A marine engineer's path through bayesid on real free-running model tests: the KVLCC2 7 m model
zigzags measured by HSVA for the SIMMAN 2008 workshop (Stern & Agdrup, eds.; files as published
with Alexandersson et al. 2022, Ocean Eng. 266:112940). Every command on this page is the command
a user types, and every output under it is what that command printed when these pages were built:

1. ``bayesid simulate``: does the vessel file fly?
2. ``bayesid convert``: the HSVA files to track CSVs;
3. ``bayesid fit``: identify the hull, propeller and rudder coefficients on a few zigzags;
4. ``bayesid predict``: score the model on zigzags it has not seen;
5. ``bayesid sample``: the posterior of the coefficients and what the tracks determine;
6. ``bayesid diagnose``: does the model miss an effect, and which?

**The data.** The HSVA runs are not part of the package (see their ``README.md`` for the source
and the terms of use). The build looks for them in the folder named by the environment variable
``BAYESID_REAL_DATA`` (the folder holding ``kvlcc2-simman-hsva/``), or else in
``../shared/data/real`` next to the repository. When they are absent, step 1 still runs; steps
2-6 print that the data were absent and show no output, and nothing on this page stands in for it.

**Run it yourself.** In an empty folder, with the HSVA files in a folder ``kvlcc2-simman-hsva``,
type the commands as shown (``bayesid`` is installed with the package; ``python -m bayesid.cli``
is the same command). Progress bars, which a terminal shows on stderr, are left out of the
outputs below; warnings are kept. The iteration budgets (``--max-nfev``, ``--draws``) are cut so
that the whole page builds in a few minutes; drop them for a real study (the defaults are shown by
``bayesid fit --help`` and the like).
"""

import html
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import bayesid
from bayesid.data.track import read_csv
from bayesid.estimation.indices import manoeuvre_indices

here = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd()  # the gallery runs in docs/examples
real = Path(os.environ.get("BAYESID_REAL_DATA", here.parents[1] / ".." / "shared" / "data" / "real"))
hsva = real / "kvlcc2-simman-hsva"
have_data = hsva.is_dir() and any(hsva.glob("HSVA_CPMC_KVLCC2_Z_*.dat"))

work = Path(tempfile.mkdtemp(prefix="bayesid_ship_tutorial_"))  # an empty folder: the commands run in it
if have_data:
    os.symlink(hsva.resolve(), work / "kvlcc2-simman-hsva", target_is_directory=True)
    status = f"HSVA runs found in {hsva}: steps 2-6 ran on them when this page was built."
else:
    status = (
        f"HSVA runs NOT FOUND when this page was built (looked in {hsva}; set BAYESID_REAL_DATA to the "
        "folder holding kvlcc2-simman-hsva/). Steps 2-6 were not run and their outputs are not shown."
    )


class Banner(str):
    """The data status as a box on the built page (the gallery shows an expression's HTML)."""

    def _repr_html_(self) -> str:
        kind, title = ("note", "Data present") if have_data else ("warning", "Data absent")
        return f'<div class="admonition {kind}"><p class="admonition-title">{title}</p><p>{html.escape(self)}</p></div>'


Banner(status)

# %%
# The two helpers below run a command line as typed and show the files it wrote.

package_root = str(Path(bayesid.__file__).parents[1])  # the commands run the bayesid these pages document
env = dict(os.environ, PYTHONPATH=os.pathsep.join([package_root, os.environ.get("PYTHONPATH", "")]))
env.update(PYTHONUNBUFFERED="1", TQDM_DISABLE="1", MPLBACKEND="Agg")
PROGRESS = re.compile(r"\d+%\|")  # a tqdm frame


def run(command: str, *, needs_data: bool = True) -> None:
    """Print a bayesid command line as typed, run it here, print its output (stdout and stderr)."""
    args = shlex.split(command)
    shown = shlex.join(args)
    if len(shown) > 90:  # one option a line, as a shell script would break it
        shown = re.sub(r" (--\S+)", r" \\\n      \1", shown)
    print(f"$ {shown}")
    if needs_data and not have_data:
        print("(not run: the HSVA runs are absent on this build)")
        return
    proc = subprocess.run(
        [sys.executable, "-m", "bayesid.cli", *args[1:]], env=env, cwd=work, capture_output=True, text=True, check=False
    )
    merged = proc.stdout + proc.stderr  # stderr holds progress bars, warnings and errors
    for line in merged.splitlines():
        kept = [part for part in line.split("\r") if not PROGRESS.search(part)]
        if kept or not line:
            print("".join(kept))
    if proc.returncode != 0:
        raise RuntimeError(f"{command!r} exited with {proc.returncode}: the tutorial no longer runs")


def cat(path: str) -> None:
    """Print a file a command wrote, as ``cat`` would."""
    if not (work / path).exists():
        print(f"(no {path}: the HSVA runs are absent on this build)" if not have_data else f"(no {path})")
        return
    print(f"$ cat {path}")
    print((work / path).read_text())


def show_figures(folder: str) -> None:
    """Show every PNG a command wrote into ``folder``, at its own size, labelled with its path."""
    pngs = sorted((work / folder).glob("*.png"))
    if not pngs:
        print(f"no figures in {folder}" + ("" if have_data else " (the HSVA runs are absent on this build)"))
    for png in pngs:
        img = plt.imread(png)
        h, w = img.shape[:2]
        fig = plt.figure(figsize=(w / 100, (h + 30) / 100), dpi=100)
        ax = fig.add_axes((0, 0, 1, h / (h + 30)))
        ax.imshow(img)
        ax.set_axis_off()
        fig.text(0.01, 1 - 15 / (h + 30), str(png.relative_to(work)), fontsize=9, va="center", family="monospace")


# %%
# 1. Does the vessel file fly?
# ----------------------------
#
# Before fitting anything, simulate a standard manoeuvre with the vessel file. ``kvlcc2_7m`` is
# the packaged KVLCC2 7 m model (``bayesid/vehicles/kvlcc2_7m.toml``: the HSVA particulars, the
# captive-test coefficients of Yasukawa & Yoshimura 2015 and the tests' approach speed and helm
# rate). A 10/10 zigzag first to starboard (``--angle`` is + to port) prints its indices by the
# ITTC definitions (:doc:`../indices`); this step needs no measured data.

run(
    "bayesid simulate --vehicle kvlcc2_7m --manoeuvre zigzag --angle -10 --check 10 --out sim_z10_10.csv",
    needs_data=False,
)

sim = read_csv(work / "sim_z10_10.csv")
fig, ax = plt.subplots(figsize=(8, 3.2))
ax.plot(sim.t, np.degrees(np.unwrap(sim["psi"])), "k", lw=1.2, label="heading (deg)")
ax.plot(sim.t, np.degrees(sim["delta_r"]), "tab:blue", lw=1.0, label="rudder (deg, + port)")
ax.set_xlabel("t (s)")
ax.set_title("sim_z10_10.csv: the packaged coefficients, simulated", fontsize=9)
ax.legend(fontsize=8)
fig.tight_layout()

# %%
# 2. Convert the HSVA files
# -------------------------
#
# ``bayesid convert`` reads the HSVA run files (model scale, degrees, rev/s, 20 Hz) and
# writes one track CSV per run in SI units and radians, with a ``# vessel:`` line that the
# packaged ``kvlcc2_7m`` accepts (``--vessel`` names another vessel file), plus ``convert.json``
# and ``convert.md`` listing every conversion. The HSVA files log position, heading, yaw rate,
# rudder and propeller speed, but not the body velocities ``u`` and ``v``: the model starts its
# windows from states estimated from the positions.

run("bayesid convert kvlcc2-simman-hsva --format simman-hsva --out tracks")
cat("tracks/convert.md")

# %%
# The head of one converted track: comments first (source, vessel, manoeuvre, every conversion),
# then the header row and the samples.

if have_data:
    lines = (work / "tracks/HSVA_CPMC_KVLCC2_Z_10_10_S.csv").read_text().splitlines()
    print("$ head -n 16 tracks/HSVA_CPMC_KVLCC2_Z_10_10_S.csv")
    print("\n".join(lines[:16]))
else:
    print("(not shown: the HSVA runs are absent on this build)")

# %%
# The measured 10/10 zigzag to starboard against the packaged model's simulation of step 1,
# both from the first rudder execute (detected from the rudder leaving its hold): how far the
# captive-test coefficients alone are from this hull's free-running zigzag, the gap the fit closes.

if have_data:
    meas = read_csv(work / "tracks/HSVA_CPMC_KVLCC2_Z_10_10_S.csv")
    fig, ax = plt.subplots(figsize=(8, 3.2))
    for trk, style, label in ((meas, "k", "measured (HSVA Z_10_10_S)"), (sim, "tab:red", "simulated (step 1)")):
        t0 = manoeuvre_indices(trk.t, trk["x"], trk["y"], trk["psi"], trk["delta_r"])["executes_t_s"][0]
        psi = np.degrees(np.unwrap(trk["psi"]))
        ax.plot(trk.t - t0, psi - np.interp(t0, trk.t, psi), style, lw=1.2, label=f"heading change, {label}")
    ax.set_xlim(0, meas.t[-1] - meas.t[0])
    ax.set_xlabel("time from the first execute (s)")
    ax.set_ylabel("deg")
    ax.legend(fontsize=8)
    fig.tight_layout()
else:
    print("(no comparison: the HSVA runs are absent on this build)")

# %%
# 3. Fit on four zigzags
# ----------------------
#
# Training runs: the 10/10 zigzag to starboard, the 20/10 to port, the 10/5 and the 35/5. The
# other zigzags stay unseen until step 4. ``bayesid fit`` frees the coefficients listed in the
# file's ``[fit] free`` (hull, propeller wake, rudder), seeds them by an equation-error
# regression, keeps the file's captive-test ``[prior]`` (a maximum-a-posteriori fit; ``--prior
# none`` fits the data alone) and fits by multiple shooting: the tracks are cut into short windows, each simulated from the
# measured state at its start. With three or more training runs it also calibrates the
# predictive bands by leaving one run out at a time (``--calibration none`` skips that).
# ``--max-nfev 20`` keeps this page quick; a study uses the default.

TRAIN = "tracks/HSVA_CPMC_KVLCC2_Z_10_10_S.csv tracks/HSVA_CPMC_KVLCC2_Z_20_10_P.csv tracks/HSVA_CPMC_KVLCC2_Z_10_05.csv tracks/HSVA_CPMC_KVLCC2_Z_35_05.csv"
run(f"bayesid fit --vehicle kvlcc2_7m --train {TRAIN} --max-nfev 20 --out fit")

# %%
# ``fit/model.json`` is the identified model for ``predict`` and ``sample``; ``fit/report.md`` is
# the same for a reader: the fit's settings, the training error, each coefficient's start and
# identified value with its standard deviation, the captive-test prior against the estimate, and
# the directions the training runs determine least.

cat("fit/report.md")
show_figures("fit/figures")

# %%
# 4. Predict zigzags the fit has not seen
# ---------------------------------------
#
# ``bayesid predict`` scores the model on held-out runs with the window protocol: each run is cut
# into windows (60 s by default, the window of the calibrated bands), each simulated open loop
# from the measured state at its start with the recorded rudder and propeller. It reports the
# position and heading errors per run and pooled, one open-loop simulation of each whole run, and
# the zigzag indices measured and predicted, with the calibrated bands and their coverage.
# (HSVA measured zigzags only; to predict turning circles, train on at least one turning circle:
# a manoeuvre kind missing from the training runs is marked *extrapolated*.)

HELDOUT = "tracks/HSVA_CPMC_KVLCC2_Z_10_10_P.csv tracks/HSVA_CPMC_KVLCC2_Z_20_10_S.csv tracks/HSVA_CPMC_KVLCC2_Z_15_05.csv tracks/HSVA_CPMC_KVLCC2_Z_25_05.csv"
run(f"bayesid predict --model fit/model.json --track {HELDOUT} --draws 40 --out pred")
cat("pred/report.md")

# %%
# The figures ``predict`` wrote: per run, the measured and predicted track and heading, and the
# reliability of the calibrated bands.

show_figures("pred/figures")

# %%
# A pooled RMS is a mean of squares, so a few bad windows can weigh as much as all the others:
# read it together with the distribution over the windows. ``pred/predict.json`` lists every
# window (``windows``); here they are sorted, worst first.

if have_data:
    windows = json.loads((work / "pred/predict.json").read_text())["windows"]
    pooled = json.loads((work / "pred/predict.json").read_text())["pooled"]["rms_position_m"]
    err = np.array([w["rms_position_m"] for w in windows])
    print(
        f"{len(err)} windows; RMS position error per window (m): median {np.median(err):.3g}, "
        f"90th percentile {np.percentile(err, 90):.3g}; pooled over all samples {pooled:.3g}"
    )
    print(f"{'track':<28} {'start (s)':>9} {'RMS (m)':>8} {'max (m)':>8} {'heading RMS (deg)':>18}")
    for w in sorted(windows, key=lambda w: -w["rms_position_m"]):
        print(
            f"{w['track']:<28} {w['t_start']:9.1f} {w['rms_position_m']:8.3f} {w['max_position_m']:8.3f} {w['rms_heading_deg']:18.2f}"
        )
else:
    print("(not computed: the HSVA runs are absent on this build)")

# %%
# 5. Sample the posterior
# -----------------------
#
# ``bayesid sample`` turns the fit into a posterior of the coefficients on the same training
# runs: importance-reweighted Laplace draws (``--method importance``; the default ``auto`` goes on
# to MCMC when the importance weights cannot be trusted, which takes longer). The verdict line
# says whether the draws are reliable, by the Pareto k-hat of the weights and their effective
# sample size; when it says *not reliable*, use ``--method mcmc`` or the default before quoting a
# posterior sd. The report tables each coefficient's prior, fit and posterior, which ones the
# tracks determine beyond their prior, the sloppiest directions and the most collinear subsets.

run(f"bayesid sample --model fit/model.json --train {TRAIN} --method importance --draws 400 --out post")
cat("post/report.md")

# %%
# The figures ``sample`` wrote: the Fisher information's spectrum, the marginals against the
# priors, pairs of the most correlated coefficients and the importance weights.

show_figures("post/figures")

# %%
# 6. Diagnose what the model misses
# ---------------------------------
#
# ``bayesid diagnose`` fits the base model on the training runs, refits it with each effect of
# the ship catalogue added (it prints the candidates it tries: wind only when the tracks log the
# wind), scores all of them on the held-out runs against the noise floor (what a perfect model
# would score at the estimated sensor noise), and gives a verdict: an effect that is the *cause*, *contributors*, ``unexplained`` for a significant
# remainder no candidate explains, or ``none``. ``--no-discover`` skips the search for missing
# model terms (structure discovery, :doc:`../gap`) to keep this page quick; ``--max-nfev 10``
# likewise.

run(f"bayesid diagnose --vehicle kvlcc2_7m --train {TRAIN} --heldout {HELDOUT} --max-nfev 10 --no-discover --out diag")
cat("diag/report.md")

# %%
# The figures ``diagnose`` wrote: the ranking of the effects, the error per channel, where (in which regions of the motion) the error grows, and a held-out track.

show_figures("diag/figures")

# %%
# Where next
# ----------
#
# * :doc:`../vessel`: the vessel file of your own ship, its ``[prior]`` and ``[fit] free``, and
#   ``convert --vessel`` for tracks of your own hull;
# * :doc:`../gap`: the diagnosis in full, with structure discovery;
# * :doc:`../posterior`: reading the posterior and the identifiability dossier.

shutil.rmtree(work, ignore_errors=True)

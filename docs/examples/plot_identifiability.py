"""
Fit six coefficients and see which combinations the data pin down
=================================================================

A noisy 20/20 zigzag of NPS AUV II is the "measured" track. Six sway and yaw coefficients are
fitted by least squares from a start 20 % off, and the Fisher information at the optimum says
which coefficient combinations the zigzag determines and which it leaves loose
(:mod:`bayesid.analysis.identifiability`). Relative units throughout: a direction
``0.7*Yv - 0.7*Yr`` means "raise Yv by 0.7 % while lowering Yr by 0.7 %".
"""

import math

import matplotlib.pyplot as plt
import numpy as np

from bayesid.analysis import identifiability as ident
from bayesid.data.vehicle import load_vehicle
from bayesid.estimation.fit import fit
from bayesid.estimation.objective import Problem
from bayesid.estimation.posterior import add_noise
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator

vehicle = load_vehicle("nps_auv2")
rng = np.random.default_rng(7)
FREE = ["Yv", "Yr", "Nv", "Nr", "Ydr", "Ndr"]
NOISE = {"x": 0.2, "y": 0.2, "psi": math.radians(0.2)}  # m, m, rad

manoeuvre = mv.zigzag(vehicle, 20.0, duration=150.0)
truth = vehicle.coefficient_vector(FREE)
measured = add_noise(
    Simulator(vehicle, manoeuvre, mode="horizontal", sample_every=10).run().track(0), NOISE, rng
)  # sampled at 1 s, noise on x, y, psi

# %%
# The fit
# -------
# :class:`~bayesid.estimation.objective.Problem` is the paper's output-error objective on the
# channels given; the optimiser works on ratios to ``reference`` (here the truth, so the true
# point is 1.0 for every coefficient).
sim = Simulator(vehicle, manoeuvre, free=FREE, mode="horizontal", sample_every=10)
problem = Problem(sim, measured, reference=truth, channels=("x", "y", "psi"))
start = 1.0 + rng.uniform(-0.2, 0.2, len(FREE))
result = fit(problem, start, (np.full(6, 0.2), np.full(6, 3.0)))
print(f"cost {result.cost:.4g}, {result.n_simulations} simulated tracks, {result.message}")
for name, s, p in zip(FREE, start, result.p):
    print(f"{name:4s} start {s:6.3f}  fitted {p:6.3f}  (truth 1)")

# %%
# Fisher information at the optimum
# ---------------------------------
# Sensitivities to relative changes, weighted by the noise: ``F = S^T S / sigma^2``. Its
# eigenvalues are the precision along each eigen-direction; the Cramer-Rao standard deviation
# along one is ``1/sqrt(lambda)``.
theta = problem.theta(result.p)
S = ident.relative_sensitivity(problem, theta)
F = ident.fisher_information(S, problem.noise_vector(NOISE))
directions = ident.eigen_directions(F, FREE)  # sloppiest first
for d in directions:
    print(f"Cramer-Rao sd {100 * d.sd_relative:8.3f} %  along  {d.label()}")
print(f"condition number {ident.condition_number(F):.3g}")

# %%
# The sloppiest direction is loose to tens of percent while the stiffest is pinned to a small
# fraction of one percent: the fit above moved the coefficients mostly along the loose ones,
# and the track cannot tell.

cov = np.linalg.inv(F)
sd = np.sqrt(np.diag(cov))
corr = cov / np.outer(sd, sd)

fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
lam = np.sort(np.linalg.eigvalsh(F))[::-1]
ax.semilogy(range(1, len(lam) + 1), 1.0 / np.sqrt(lam), "o-")
ax.set(
    xlabel="eigen-direction (best determined first)",
    ylabel="Cramer-Rao sd, relative",
    title="how well each direction is determined",
)
im = ax2.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
ax2.set_xticks(range(6), FREE)
ax2.set_yticks(range(6), FREE)
for i in range(6):
    for j in range(6):
        ax2.text(j, i, f"{corr[i, j]:.2f}", ha="center", va="center", fontsize=7)
ax2.set_title("correlation of the estimates (from F^-1)")
fig.colorbar(im, ax=ax2, shrink=0.8)
fig.tight_layout()
plt.show()

# %%
# Collinearity
# ------------
# The collinearity index of a subset (Brun, Reichert & Kuensch 2001) measures how far a
# combination of those columns of ``S`` can cancel; Brun et al. take 10-15 as the level above
# which the subset is poorly identifiable together.
for row in ident.collinearity_table(S, FREE, sizes=(2, 3), top=5):
    print(f"{' + '.join(row['subset']):16s} collinearity index {row['gamma']:6.1f}")

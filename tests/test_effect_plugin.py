"""An effect is one class in one file (issue 22): a yaw-moment bias defined only here is used to
make world data, then ranked, attributed and supported by the gap diagnosis, with no change to
the package."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from bayesid.analysis.gap import DiagnoseOptions, Diagnosis, diagnose
from bayesid.data.vehicle import load_vehicle
from bayesid.models import effects as ef
from bayesid.models import manoeuvres as mv
from bayesid.models.world import world_track


@dataclass(frozen=True, eq=False)
class YawBias(ef.Effect):
    """A constant yaw moment (an asymmetric appendage or a trimmed-off rudder): an external
    moment N0 on the yaw equation."""

    def exo(self, ctx, inputs, q, nu):
        col = np.ones((q.shape[0], ctx.n_steps, 1))
        coef = np.zeros((q.shape[0], 1, 6))
        coef[:, 0, 5] = q[:, 0]
        return col, coef

    def force_signature(self, m):
        z = np.zeros(m["t"].size)
        return [np.column_stack([z, z, np.ones_like(z)])]


YAW_BIAS = YawBias(
    "yaw_bias",
    ("N0_Nm",),
    (-400.0,),
    (400.0,),
    (0.0,),
    (20.0,),
    neutral=(0.0,),
    exo_columns=1,
    description="constant yaw moment",
)


@pytest.fixture(scope="module")
def diagnosis():
    veh = load_vehicle("nps_auv2")
    rng = np.random.default_rng(3)
    truth = {YAW_BIAS: {"N0_Nm": 60.0}}
    train = [
        world_track(veh, m, truth, rng, name=f"train_{k}")
        for k, m in enumerate(
            [
                mv.zigzag(veh, 20.0, dt=0.1, duration=150.0),
                mv.prbs(veh, 15.0, duration=150.0, rng=np.random.default_rng(1)),
            ]
        )
    ]
    held = [world_track(veh, mv.zigzag(veh, 10.0, dt=0.1, duration=150.0, first_sign=-1), truth, rng, name="heldout")]
    return diagnose(
        veh,
        ["Yv", "Nr", "Ndr"],
        train,
        held,
        DiagnoseOptions(candidates=[YAW_BIAS, "thrust", "delay"], window_s=60.0, max_nfev=30, max_effects=1),
        rng=np.random.default_rng(0),
    )


def test_an_effect_defined_outside_the_package_is_ranked_and_attributed(diagnosis):
    d = diagnosis
    assert isinstance(d, Diagnosis)
    assert d.verdict == "yaw_bias", [(r["effect"], r["heldout_rms_m"], r["role"]) for r in d.ranking]
    assert d.ranking[0]["effect"] == "yaw_bias" and d.cause == "yaw_bias"
    assert d.ranking[0]["parameters"]["N0_Nm"] == pytest.approx(60.0, rel=0.3)
    assert d.gap_after["heldout_rms_m"] < 0.5 * d.gap_before["heldout_rms_m"]
    # its force signature reaches the sparse-regression support
    assert "yaw_bias" in d.sindy_support and d.sindy_support["yaw_bias"] > 0.5
    assert d.to_dict()["settings"]["candidates"] == ["yaw_bias", "thrust", "delay"]

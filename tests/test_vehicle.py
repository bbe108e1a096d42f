"""Vehicle files and the term library."""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bayesid.data import terms
from bayesid.data.vehicle import VehicleFileError, load_vehicle

PACKAGED = Path(__file__).resolve().parents[1] / "bayesid" / "vehicles" / "nps_auv2.toml"


def _edited(tmp_path, old, new, count=1):
    text = PACKAGED.read_text()
    assert old in text, old
    p = tmp_path / "edited.toml"
    p.write_text(text.replace(old, new, count))
    return p


def test_packaged_vehicle_loads(nps):
    assert nps.L == 5.3 and nps.mass == 5454.54
    assert nps.coefficients["Yv"] == -0.1 and nps.coefficients["Cd0"] == 0.00385
    assert nps.crossflow_model == "polynomial"
    assert nps.coefficients["Yvabsv"] < 0 and nps.coefficients["Nabsvr"] < 0
    # the steady speed at 1500 rpm is the file's nominal speed (eta = 1)
    assert nps.steady_speed(1500.0) == pytest.approx(nps.nominal_speed, rel=1e-4)


def test_unknown_coefficient_names_key_and_file(tmp_path):
    p = _edited(tmp_path, "Yv = -1.0e-1", "Yvv_typo = -1.0e-1")
    with pytest.raises(terms.UnknownCoefficientError, match=r"edited\.toml.*Yvv_typo"):
        load_vehicle(p)


def test_misspelt_name_suggests_the_right_one():
    with pytest.raises(terms.UnknownCoefficientError, match="did you mean.*Yvabsv"):
        terms.term("Yvabvs")


@pytest.mark.parametrize(
    "old,new,match",
    [
        ("Izz = 13587.0\n", "", r"edited\.toml.*\[inertia\] Izz"),  # missing mass property
        ("mass_kg = 5454.54", "# no mass", r"mass_kg"),
        ("Nr = -1.6e-2", "Nr = nan", r"edited\.toml.*\[coefficients\] Nr"),  # non-finite value
        ("length_m = 5.3", "length_m = inf", r"length_m"),
    ],
)
def test_bad_vehicle_file_names_the_key(tmp_path, old, new, match):
    with pytest.raises(VehicleFileError, match=match):
        load_vehicle(_edited(tmp_path, old, new))


def test_with_coefficients_rejects_bad_input(nps):
    with pytest.raises(terms.UnknownCoefficientError, match="Yvvvv"):  # quartic: no prime product
        nps.with_coefficients({"Yvvvv": 1.0})
    with pytest.raises(ValueError, match="Nr"):
        nps.with_coefficients({"Nr": float("nan")})


def test_every_file_coefficient_is_a_term():
    """Every coefficient of the packaged file (and of the shared original, when present) is in the
    term library."""
    files = [PACKAGED, PACKAGED.parents[3] / "shared" / "data" / "vehicles" / "nps_auv2.toml"]
    for f in files:
        if not f.exists():
            continue
        names = list(tomllib.loads(f.read_text())["coefficients"])
        assert len(names) >= 90, f
        assert [n for n in names if n not in terms.INDEX] == [], f


@pytest.mark.parametrize(
    "name,k",
    [
        ("Xrr", 4),
        ("Xudot", 3),
        ("Xvr", 3),
        ("Xqds", 3),
        ("Xvv", 2),
        ("Xdsds_eps", 2),
        ("Cd0", 2),
        ("Yrdot", 4),
        ("Yvdot", 3),
        ("Yr", 3),
        ("Yv", 2),
        ("Ydr", 2),
        ("Yvabsr", 3),
        ("Yrabsr", 4),
        ("Kpdot", 5),
        ("Kvdot", 4),
        ("Kp", 4),
        ("Kv", 3),
        ("Mqdot", 5),
        ("Mwdot", 4),
        ("Mq", 4),
        ("Nrdot", 5),
        ("Nvdot", 4),
        ("Nr", 4),
        ("Nv", 3),
        ("Ndr", 3),
        ("Nabsvr", 4),
        ("Nrabsr", 5),
    ],
)
def test_prime_power_of_L(name, k):
    """The power of L follows the prime rule (coefficients.md tables)."""
    assert terms.term(name).L_power == k


def test_categories_for_case2():
    static = set(terms.names_where(category="static", horizontal=True))
    assert {"Yv", "Ydr", "Nv", "Ndr", "Xvv", "Xvdr", "Xdrdr", "Cd0", "Yvabsv", "Nvabsv"} <= static
    rotary = set(terms.names_where(category="rotary", horizontal=True))
    assert {"Yr", "Nr", "Xrr", "Xvr", "Xrdr", "Yvabsr", "Nabsvr"} <= rotary
    assert not static & rotary
    assert set(terms.names_where(kind="added_mass", horizontal=True)) == {"Xudot", "Yvdot", "Yrdot", "Nvdot", "Nrdot"}


def test_mass_matrix_symmetric_and_added_mass(nps):
    M = nps.mass_matrix()
    assert np.allclose(
        M, M.T, atol=1e-9 * np.abs(M).max()
    )  # NPS added-mass cross terms are symmetric (Yrdot = Nvdot, ...)
    M0 = nps.mass_matrix({})
    assert np.allclose(M0, M0.T)
    assert M[1, 5] - M0[1, 5] == pytest.approx(-0.5 * nps.rho * nps.L**4 * nps.coefficients["Yrdot"])
    assert M0[0, 0] == nps.mass and M0[5, 5] == nps.inertia[2, 2]
    assert math.isclose(M0[3, 1], -nps.mass * nps.rG[2])  # K row, v-dot column: -m zG

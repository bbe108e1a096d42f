"""A ship file's ``[form]`` section (issue 67, model-form alternatives): ``coupling_speed = "U"``
divides the hull's coupling terms by MMG 2015's ``U`` instead of the package's ``Ut``; a key or
choice the package does not have is refused naming the file, section and key."""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from bayesid.models.ship import dynamics, layout, load_ship
from bayesid.models.ship.fileformat import ShipFileError

KVLCC2 = Path(str(resources.files("bayesid") / "vehicles" / "kvlcc2_7m.toml"))


def _file(tmp_path, form_text: str) -> Path:
    p = tmp_path / "kvlcc2_form.toml"
    p.write_text(KVLCC2.read_text() + "\n" + form_text)
    return p


def _hull_sway_yaw(ship, u, v, r):
    """Y, N of the hull and the coupling terms alone (every other force term zeroed)."""
    keep = ("Yvvr", "Yvrr", "Nvvr", "Nvrr")
    zero = {k: 0.0 for k in layout.COEFFICIENTS if k not in keep and k not in ("mx", "my", "Jz")}
    prm = ship.with_coefficients(zero).params()
    prm[[layout.PARTICULAR_INDEX["A_rudder"], layout.PARTICULAR_INDEX["D_prop"]]] = 0.0
    out = np.empty((1, 3))
    dynamics.forces(np.array([[0.0, 0.0, 0.0, u, v, r]]), np.zeros((1, 2)), np.zeros((1, 2)), np.zeros(2), prm, out)
    return out[0, 1], out[0, 2]


def test_the_mmg_coupling_speed_is_read_from_the_file_and_used(tmp_path):
    ship = load_ship(_file(tmp_path, '[form]\ncoupling_speed = "U"\n'))
    base = load_ship("kvlcc2_7m")
    assert ship.form == {"coupling_speed": "U"} and base.form == {}
    assert ship.params()[layout.FORM_INDEX["coupling_rL"]] == 0.0
    assert base.params()[layout.FORM_INDEX["coupling_rL"]] == 1.0
    assert base.with_form(coupling_speed="U").params()[layout.FORM_INDEX["coupling_rL"]] == 0.0
    # a hard turn's state (r' = 0.9): MMG's v'^2 r' U^2 = v^2 (rL) / U, the package's / sqrt(U^2 + (rL)^2)
    c, L = ship.coefficients, ship.L
    u, v, r = 0.41, -0.14, 0.9 * math.hypot(0.41, 0.14) / L
    q = 0.5 * ship.rho * L * ship.particulars["d"]
    rl, U = r * L, math.hypot(u, v)
    y_mmg = q * (c["Yvvr"] * v * v * rl + c["Yvrr"] * v * rl * rl) / U
    n_mmg = q * L * (c["Nvvr"] * v * v * rl + c["Nvrr"] * v * rl * rl) / U
    y, n = _hull_sway_yaw(ship, u, v, r)
    assert y == pytest.approx(y_mmg, rel=1e-12) and n == pytest.approx(n_mmg, rel=1e-12)
    y0, n0 = _hull_sway_yaw(base, u, v, r)
    ratio = U / math.hypot(U, rl)  # 0.743 at r' = 0.9
    assert y0 == pytest.approx(y_mmg * ratio, rel=1e-12) and n0 == pytest.approx(n_mmg * ratio, rel=1e-12)


@pytest.mark.parametrize(
    "text, match",
    [
        ('[form]\ncoupling_speed = "V"\n', r"\[form\] coupling_speed = 'V'; the choices are 'Ut', 'U'"),
        ('[form]\ncoupling = "U"\n', r"\[form\] unknown key 'coupling'; known: coupling_speed"),
        ('form = "U"\n', r"form = 'U' must be a section \[form\]"),
    ],
)
def test_a_form_the_package_does_not_have_is_refused_naming_it(tmp_path, text, match):
    p = _file(tmp_path, text) if text.startswith("[") else None
    if p is None:  # a top-level key must come before the first section
        p = tmp_path / "kvlcc2_form.toml"
        p.write_text(text + KVLCC2.read_text())
    with pytest.raises(ShipFileError, match=match) as e:
        load_ship(p)
    assert str(p) in str(e.value)
    with pytest.raises(ShipFileError, match="the choices are"):
        load_ship("kvlcc2_7m").with_form(coupling_speed="mmg")

"""Term names users bring: every SNAME product of the term library's features is a term.

The listed table (``terms.LISTED``) loads exactly as before; other products (``Nvabsr``,
``Yrabsv``, ...) are read from their names with the right degree of freedom, factors, power of L
and multiplicity, and act in both the generated and the interpreted kernels; names that are not
products fail with the closest names.
"""

import pickle
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bayesid.data import terms
from bayesid.data.vehicle import load_vehicle, packaged_vehicles
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator

ROOT = Path(__file__).resolve().parents[1]
REMUS = ROOT / "bayesid" / "vehicles" / "remus100.toml"

# The listed table as it was before products were read from names (name, group, factors, accel,
# multiplicity, power of L, category, horizontal), written out so that a change shows here.
LISTED_BEFORE = [
    ("Xpp", "X", "p p", -1, 1, 4, "rotary", False),
    ("Xqq", "X", "q q", -1, 1, 4, "rotary", False),
    ("Xrr", "X", "r r", -1, 1, 4, "rotary", True),
    ("Xpr", "X", "p r", -1, 1, 4, "rotary", False),
    ("Xudot", "X", "", 0, 1, 3, "added_mass", True),
    ("Xwq", "X", "w q", -1, 1, 3, "rotary", False),
    ("Xvp", "X", "v p", -1, 1, 3, "rotary", False),
    ("Xvr", "X", "v r", -1, 1, 3, "rotary", True),
    ("Xqds", "X", "u q ds", -1, 1, 3, "rotary", False),
    ("Xqdb", "X", "u q db", -1, 2, 3, "rotary", False),
    ("Xrdr", "X", "u r dr", -1, 1, 3, "rotary", True),
    ("Xvv", "X", "v v", -1, 1, 2, "static", True),
    ("Xww", "X", "w w", -1, 1, 2, "static", False),
    ("Xvdr", "X", "u v dr", -1, 1, 2, "static", True),
    ("Xwds", "X", "u w ds", -1, 1, 2, "static", False),
    ("Xwdb", "X", "u w db", -1, 2, 2, "static", False),
    ("Xdsds", "X", "u u ds ds", -1, 1, 2, "static", False),
    ("Xdbdb", "X", "u u db db", -1, 1, 2, "static", False),
    ("Xdrdr", "X", "u u dr dr", -1, 1, 2, "static", True),
    ("Xqds_eps", "X", "u q ds eps", -1, 1, 3, "rotary", False),
    ("Xwds_eps", "X", "u w ds eps", -1, 1, 2, "static", False),
    ("Xdsds_eps", "X", "u u ds ds eps", -1, 1, 2, "static", False),
    ("Cd0", "X", "prop", -1, 1, 2, "static", True),
    ("Ypdot", "Y", "", 3, 1, 4, "added_mass", False),
    ("Yrdot", "Y", "", 5, 1, 4, "added_mass", True),
    ("Ypq", "Y", "p q", -1, 1, 4, "rotary", False),
    ("Yqr", "Y", "q r", -1, 1, 4, "rotary", False),
    ("Yvdot", "Y", "", 1, 1, 3, "added_mass", True),
    ("Yp", "Y", "u p", -1, 1, 3, "rotary", False),
    ("Yr", "Y", "u r", -1, 1, 3, "rotary", True),
    ("Yvq", "Y", "v q", -1, 1, 3, "rotary", False),
    ("Ywp", "Y", "w p", -1, 1, 3, "rotary", False),
    ("Ywr", "Y", "w r", -1, 1, 3, "rotary", False),
    ("Yv", "Y", "u v", -1, 1, 2, "static", True),
    ("Yvw", "Y", "v w", -1, 1, 2, "static", False),
    ("Ydr", "Y", "u u dr", -1, 1, 2, "static", True),
    ("Yvabsv", "Y", "v |v|", -1, 1, 2, "static", True),
    ("Yvabsr", "Y", "v |r|", -1, 1, 3, "rotary", True),
    ("Yrabsr", "Y", "r |r|", -1, 1, 4, "rotary", True),
    ("Zqdot", "Z", "", 4, 1, 4, "added_mass", False),
    ("Zpp", "Z", "p p", -1, 1, 4, "rotary", False),
    ("Zpr", "Z", "p r", -1, 1, 4, "rotary", False),
    ("Zrr", "Z", "r r", -1, 1, 4, "rotary", False),
    ("Zwdot", "Z", "", 2, 1, 3, "added_mass", False),
    ("Zq", "Z", "u q", -1, 1, 3, "rotary", False),
    ("Zvp", "Z", "v p", -1, 1, 3, "rotary", False),
    ("Zvr", "Z", "v r", -1, 1, 3, "rotary", False),
    ("Zw", "Z", "u w", -1, 1, 2, "static", False),
    ("Zvv", "Z", "v v", -1, 1, 2, "static", False),
    ("Zds", "Z", "u u ds", -1, 1, 2, "static", False),
    ("Zdb", "Z", "u u db", -1, 2, 2, "static", False),
    ("Zq_eps", "Z", "u q eps", -1, 1, 3, "rotary", False),
    ("Zw_eps", "Z", "u w eps", -1, 1, 2, "static", False),
    ("Zds_eps", "Z", "u u ds eps", -1, 1, 2, "static", False),
    ("Zwabsw", "Z", "w |w|", -1, 1, 2, "static", False),
    ("Zwabsq", "Z", "w |q|", -1, 1, 3, "rotary", False),
    ("Zqabsq", "Z", "q |q|", -1, 1, 4, "rotary", False),
    ("Kpdot", "K", "", 3, 1, 5, "added_mass", False),
    ("Krdot", "K", "", 5, 1, 5, "added_mass", False),
    ("Kpq", "K", "p q", -1, 1, 5, "rotary", False),
    ("Kqr", "K", "q r", -1, 1, 5, "rotary", False),
    ("Kvdot", "K", "", 1, 1, 4, "added_mass", False),
    ("Kp", "K", "u p", -1, 1, 4, "rotary", False),
    ("Kr", "K", "u r", -1, 1, 4, "rotary", False),
    ("Kvq", "K", "v q", -1, 1, 4, "rotary", False),
    ("Kwp", "K", "w p", -1, 1, 4, "rotary", False),
    ("Kwr", "K", "w r", -1, 1, 4, "rotary", False),
    ("Kv", "K", "u v", -1, 1, 3, "static", False),
    ("Kvw", "K", "v w", -1, 1, 3, "static", False),
    ("Kdb", "K", "u u db", -1, 2, 3, "static", False),
    ("Kp_eps", "K", "u p eps", -1, 1, 4, "rotary", False),
    ("Kprop", "K", "u u", -1, 1, 3, "static", False),
    ("Mqdot", "M", "", 4, 1, 5, "added_mass", False),
    ("Mpp", "M", "p p", -1, 1, 5, "rotary", False),
    ("Mpr", "M", "p r", -1, 1, 5, "rotary", False),
    ("Mrr", "M", "r r", -1, 1, 5, "rotary", False),
    ("Mwdot", "M", "", 2, 1, 4, "added_mass", False),
    ("Mq", "M", "u q", -1, 1, 4, "rotary", False),
    ("Mvp", "M", "v p", -1, 1, 4, "rotary", False),
    ("Mvr", "M", "v r", -1, 1, 4, "rotary", False),
    ("Mw", "M", "u w", -1, 1, 3, "static", False),
    ("Mvv", "M", "v v", -1, 1, 3, "static", False),
    ("Mds", "M", "u u ds", -1, 1, 3, "static", False),
    ("Mdb", "M", "u u db", -1, 2, 3, "static", False),
    ("Mq_eps", "M", "u q eps", -1, 1, 4, "rotary", False),
    ("Mw_eps", "M", "u w eps", -1, 1, 3, "static", False),
    ("Mds_eps", "M", "u u ds eps", -1, 1, 3, "static", False),
    ("Mwabsw", "M", "w |w|", -1, 1, 3, "static", False),
    ("Mabswq", "M", "|w| q", -1, 1, 4, "rotary", False),
    ("Mqabsq", "M", "q |q|", -1, 1, 5, "rotary", False),
    ("Npdot", "N", "", 3, 1, 5, "added_mass", False),
    ("Nrdot", "N", "", 5, 1, 5, "added_mass", True),
    ("Npq", "N", "p q", -1, 1, 5, "rotary", False),
    ("Nqr", "N", "q r", -1, 1, 5, "rotary", False),
    ("Nvdot", "N", "", 1, 1, 4, "added_mass", True),
    ("Np", "N", "u p", -1, 1, 4, "rotary", False),
    ("Nr", "N", "u r", -1, 1, 4, "rotary", True),
    ("Nvq", "N", "v q", -1, 1, 4, "rotary", False),
    ("Nwp", "N", "w p", -1, 1, 4, "rotary", False),
    ("Nwr", "N", "w r", -1, 1, 4, "rotary", False),
    ("Nv", "N", "u v", -1, 1, 3, "static", True),
    ("Nvw", "N", "v w", -1, 1, 3, "static", False),
    ("Ndr", "N", "u u dr", -1, 1, 3, "static", True),
    ("Nprop", "N", "u u", -1, 1, 3, "static", True),
    ("Nvabsv", "N", "v |v|", -1, 1, 3, "static", True),
    ("Nabsvr", "N", "|v| r", -1, 1, 4, "rotary", True),
    ("Nrabsr", "N", "r |r|", -1, 1, 5, "rotary", True),
]


@pytest.fixture(autouse=True)
def _table_restored():
    """Products a test names stay out of the test files after this one: the table grows for the
    rest of a process (``names_where`` lists them), and some tests compare whole name sets."""
    saved = terms.TERMS, terms.NAMES, dict(terms.INDEX)
    yield
    terms.TERMS, terms.NAMES = saved[:2]
    terms.INDEX.clear()
    terms.INDEX.update(saved[2])


def test_listed_terms_load_as_before():
    assert terms.LISTED == tuple(row[0] for row in LISTED_BEFORE)
    assert terms.NAMES[: len(terms.LISTED)] == terms.LISTED
    for name, group, factors, accel, mult, k, category, horizontal in LISTED_BEFORE:
        t = terms.term(name)
        assert terms.INDEX[name] == terms.LISTED.index(name)
        assert (t.group, " ".join(t.factors), t.accel, t.multiplicity, t.L_power, t.category, t.horizontal) == (
            group,
            factors,
            accel,
            mult,
            k,
            category,
            horizontal,
        ), name
        assert terms.parse(name) is t


@pytest.mark.parametrize("name", [n for n in terms.LISTED if n not in ("Cd0", "Kprop", "Nprop")])
def test_the_grammar_reads_every_listed_name_as_listed(name):
    """The name grammar alone (no table look-up) gives each listed term, so listed and new
    products follow one rule."""
    t = terms._read(name)
    listed = terms.term(name)
    assert (t.dof, t.factors, t.accel, t.L_power) == (listed.dof, listed.factors, listed.accel, listed.L_power)
    assert t.multiplicity == listed.multiplicity or name == "Xdbdb"


@pytest.mark.parametrize(
    "name,group,factors,k,category,horizontal",
    [
        ("Nvabsr", "N", ("v", "|r|"), 4, "rotary", True),  # N from v|r|: one rate, a moment
        ("Yrabsv", "Y", ("r", "|v|"), 3, "rotary", True),
        ("Nabsrv", "N", ("|r|", "v"), 4, "rotary", True),  # another spelling of a new product
        ("Yq", "Y", ("u", "q"), 3, "rotary", False),  # implicit u
        ("Yvv", "Y", ("v", "v"), 2, "static", True),
        ("Mwabsq", "M", ("w", "|q|"), 4, "rotary", False),
        ("Ndrdrdr", "N", ("u", "u", "dr", "dr", "dr"), 3, "static", True),
        ("Mq_eps", "M", ("u", "q", "eps"), 4, "rotary", False),  # listed: same rule
        ("Nconst", "N", (), 3, "static", True),  # the same at every speed: no factor at all
        ("Yconst", "Y", (), 2, "static", True),
    ],
)
def test_new_products_load_with_their_factors_and_power_of_L(name, group, factors, k, category, horizontal):
    t = terms.term(name)
    assert (t.group, t.factors, t.L_power, t.category, t.horizontal, t.multiplicity) == (
        group,
        factors,
        k,
        category,
        horizontal,
        1,
    )
    assert terms.NAMES[terms.INDEX[name]] == name and terms.TERMS[terms.INDEX[name]] is t


def test_new_products_multiplicity_and_accelerations():
    assert terms.term("Ndb").factors == ("u", "u", "db") and terms.term("Ndb").multiplicity == 2
    assert terms.term("Ndb").L_power == 3
    t = terms.term("Xvdot")
    assert (t.kind, t.group, t.accel, t.L_power, t.category) == ("added_mass", "X", 1, 3, "added_mass")
    assert terms.term("Kqdot").L_power == 5


def test_Kpabsp_loads():
    t = terms.term("Kpabsp")
    assert (t.group, t.factors, t.L_power, t.category) == ("K", ("p", "|p|"), 5, "rotary")


@pytest.mark.parametrize(
    "name,match",
    [
        ("Yvabvs", r"unknown coefficient 'Yvabvs': cannot read 'abvs'.*did you mean Yvabsv"),
        ("Nvabsx", r"cannot read 'absx'.*did you mean Nvabsv"),
        ("Yvvvv", r"4 velocity factors; a prime-form term has at most 3"),
        ("Xuabsu", r"\|u\| is not a feature"),
        ("Xdrdrdrdr", r"6 factors .*at most 5"),
        ("Qv", r"force letter"),
        ("N", r"no factor"),
        ("Nr_eta", r"cannot read '_eta'.*then optionally _eps"),
        ("Yabsvv", r"'Yabsvv' is the product \|v\|\*v in Y, listed as 'Yvabsv'"),
        ("Kuu", r"listed as 'Kprop'"),
        ("Yvudot", r"cannot read"),
    ],
)
def test_names_that_are_not_products_fail_with_suggestions(name, match):
    n_before = len(terms.NAMES)
    with pytest.raises(terms.UnknownCoefficientError, match=match):
        terms.term(name)
    assert name not in terms.INDEX and len(terms.NAMES) == n_before
    with pytest.raises(terms.UnknownCoefficientError, match=match):
        terms.check_names(["Yv", name], "free coefficients")


def _edited_nps(tmp_path, extra):
    text = (ROOT / "bayesid" / "vehicles" / "nps_auv2.toml").read_text()
    p = tmp_path / "nps_extra.toml"
    p.write_text(text.replace("[coefficients]\n", "[coefficients]\n" + extra, 1))
    return p


def test_vehicle_file_with_new_products(tmp_path):
    v = load_vehicle(_edited_nps(tmp_path, "Nvabsr = -0.004\nYrabsv = 0.001\n"))
    assert v.coefficients["Nvabsr"] == -0.004
    vec = v.coefficient_vector()
    assert vec[terms.INDEX["Nvabsr"]] == -0.004 and vec[terms.INDEX["Yrabsv"]] == 0.001
    assert np.allclose(terms.prime_scale(["Nvabsr"], v.rho, v.L), 0.5 * v.rho * v.L**4)
    with pytest.raises(terms.UnknownCoefficientError, match=r"nps_extra\.toml.*Nvabsx.*did you mean"):
        load_vehicle(_edited_nps(tmp_path, "Nvabsx = -0.004\n"))


@pytest.mark.parametrize("kernel", ["generated", "interpreted"])
def test_a_new_product_acts_in_both_kernels(nps, kernel):
    """Nvabsr (N from v|r|) changes the track, identically in both kernels, and its force is
    0.5 rho L^4 Nvabsr v|r|."""
    m = mv.zigzag(nps, 20.0, duration=40.0)
    sim = Simulator(nps, m, free=["Nvabsr"], mode="horizontal", kernel=kernel)
    assert "Nvabsr" in sim.force_names
    res = sim.run([[0.0], [-0.02]])
    base = Simulator(nps, m, mode="horizontal", kernel=kernel).run()
    np.testing.assert_array_equal(res.states[0], base.states[0])  # zero value: no effect
    assert np.max(np.abs(res.states[1, :, :2] - res.states[0, :, :2])) > 0.1  # metres
    # the same coefficient given by the vehicle instead of the free list
    fixed = Simulator(nps.with_coefficients({"Nvabsr": -0.02}), m, mode="horizontal", kernel=kernel).run()
    np.testing.assert_array_equal(fixed.states[0], res.states[1])
    other = Simulator(
        nps, m, free=["Nvabsr"], mode="horizontal", kernel="interpreted" if kernel == "generated" else "generated"
    ).run([[-0.02]])
    np.testing.assert_allclose(other.states[0], res.states[1], rtol=0, atol=1e-9)
    feats = np.zeros((1, terms.N_FEATURES))
    feats[0, terms.F_INDEX["1"]] = 1.0  # the padding feature of the factor table
    feats[0, terms.F_INDEX["v"]], feats[0, terms.F_INDEX["|r|"]] = 0.3, 0.05
    phi = terms.regressors(feats, ["Nvabsr"], nps.rho, nps.L)
    assert phi[0, 0] == pytest.approx(0.5 * nps.rho * nps.L**4 * 0.3 * 0.05)


@pytest.mark.parametrize("kernel", ["generated", "interpreted"])
def test_a_constant_moment_is_the_same_at_every_speed(nps, kernel):
    """Nconst is 0.5 rho L^3 Nconst N m at any speed, where Nprop (u^2) grows with the speed; it acts
    identically in both kernels, and the two constants are not spellings of each other."""
    assert terms.listed_name("Nconst") is None and terms.listed_name("Nuu") == "Nprop"
    feats = np.zeros((3, terms.N_FEATURES))
    feats[:, terms.F_INDEX["1"]] = 1.0
    feats[:, terms.F_INDEX["u"]] = [0.5, 1.0, 2.0]
    phi = terms.regressors(feats, ["Nconst", "Nprop"], nps.rho, nps.L)
    np.testing.assert_allclose(phi[:, 0], 0.5 * nps.rho * nps.L**3)
    np.testing.assert_allclose(phi[:, 1], 0.5 * nps.rho * nps.L**3 * np.array([0.25, 1.0, 4.0]))
    m = mv.zigzag(nps, 20.0, duration=40.0)
    res = Simulator(nps, m, free=["Nconst"], mode="horizontal", kernel=kernel).run([[0.0], [0.002]])
    np.testing.assert_array_equal(res.states[0], Simulator(nps, m, mode="horizontal", kernel=kernel).run().states[0])
    assert np.max(np.abs(res.states[1, :, :2] - res.states[0, :, :2])) > 0.1  # metres
    other = Simulator(
        nps, m, free=["Nconst"], mode="horizontal", kernel="interpreted" if kernel == "generated" else "generated"
    ).run([[0.002]])
    np.testing.assert_allclose(other.states[0], res.states[1], rtol=0, atol=1e-9)


def test_a_pickled_vehicle_keeps_its_new_products_in_a_fresh_process(nps):
    """What joblib/loky and Dask workers (diagnose --jobs, --scheduler) do with a vehicle."""
    blob = pickle.dumps(nps.with_coefficients({"Nvabsr": -0.02}))
    code = (
        "import pickle, sys\n"
        "from bayesid.models import manoeuvres as mv\n"
        "from bayesid.models.simulate import Simulator\n"
        "v = pickle.loads(sys.stdin.buffer.read())\n"
        "sim = Simulator(v, mv.zigzag(v, 20.0, duration=10.0), mode='horizontal')\n"
        "print('Nvabsr' in sim.force_names)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], input=blob, capture_output=True, check=True)
    assert out.stdout.decode().strip() == "True"


@pytest.mark.parametrize("vid", ["kvlcc2_7m_mmg", "KVLCC2_7m_MMG"])
def test_a_docs_example_asked_for_by_id_is_refused_naming_its_file(vid, tmp_path, capsys):
    """A vehicle file of the docs that is not packaged (the MMG-2015 KVLCC2), asked for by its id:
    the error says so and names the file, which exists (exit code 2 from the command)."""
    from bayesid.cli import main
    from bayesid.data.vehicle import DOCS_EXAMPLES
    from bayesid.models.ship import load_ship

    path = DOCS_EXAMPLES[vid.lower()]
    assert (ROOT / path).is_file()
    for load in (load_vehicle, load_ship):
        with pytest.raises(FileNotFoundError, match=f"not packaged: its file is {path}"):
            load(vid)
    assert main(["simulate", "--vehicle", vid, "--manoeuvre", "turn", "--out", str(tmp_path / "t.csv")]) == 2
    assert path in capsys.readouterr().err


def test_remus100_is_packaged_loads_by_id_and_simulates():
    """Issue 69: REMUS 100 (Prestero 2001 converted to prime form by the docs' example) is packaged:
    it loads by its id, as the file the docs' example checks, has the converted values and its
    source, and turns in a short horizontal-plane run in both kernels."""
    assert "remus100" in packaged_vehicles()
    v = load_vehicle("remus100")
    assert v.coefficients == load_vehicle(REMUS).coefficients
    assert "Prestero" in tomllib.loads(REMUS.read_text())["source"]["citation"][0]
    assert (v.id, v.L, v.rho, v.mass) == ("remus100", 1.33, 1030.0, 30.48)
    half = 0.5 * 1030.0
    # Prestero's dimensional values over 0.5 rho L^k (Nuv -> Nv, Yur -> Yr, Nuudr -> Ndr, Mrp -> Mpr)
    assert v.coefficients["Nv"] == pytest.approx(-24.0 / (half * 1.33**3), rel=1e-6)
    assert v.coefficients["Yr"] == pytest.approx(5.22 / (half * 1.33**3), rel=1e-6)
    assert v.coefficients["Ndr"] == pytest.approx(-6.15 / (half * 1.33**3), rel=1e-6)
    assert v.coefficients["Mpr"] == pytest.approx(4.86 / (half * 1.33**5), rel=1e-6)
    assert v.coefficients["Cd0"] == pytest.approx(1.62 / (half * 1.33**2), rel=1e-6)
    assert v.nominal_speed == pytest.approx(np.sqrt(3.86 / 1.62), rel=1e-3)
    m = mv.turning_circle(v, 15.0, duration=30.0, dt=0.05)
    runs = [Simulator(v, m, mode="horizontal", kernel=k).run() for k in ("generated", "interpreted")]
    assert runs[0].status[0] == 0
    np.testing.assert_allclose(runs[0].states, runs[1].states, rtol=0, atol=1e-9)
    u, r = runs[0].states[0, -1, 6], runs[0].states[0, -1, 11]
    assert 0.5 < u < 1.6 and abs(r) > 0.05  # slowed down in a steady turn


def test_the_horizontal_library_does_not_grow_with_products_read_before():
    """A SINDy library (inverse.horizontal_terms) is the listed terms, whatever this process
    read before: reading a new product does not add a column to it."""
    from bayesid.models import inverse

    before = {g: inverse.horizontal_terms(g) for g in inverse.EQUATIONS}
    terms.term("Nvabsr")
    terms.term("Yrabsv")
    assert {g: inverse.horizontal_terms(g) for g in inverse.EQUATIONS} == before
    assert "Nvabsr" not in before["N"] and "Nvabsr" in terms.names_where(group="N")

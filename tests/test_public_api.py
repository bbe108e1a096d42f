"""The public API (issue 51): ``import bayesid`` gives the names a study needs, imported from
their modules at first use, so the import itself stays cheap; ``bayesid.diagnose`` leaves out
the catalogue effects whose columns the tracks lack, as ``bayesid diagnose`` does."""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

import bayesid

ROOT = Path(__file__).resolve().parents[1]

#: what a study reads, fits, predicts, samples and diagnoses with
EXPECTED = {
    "Track",
    "read_csv",
    "write_csv",
    "load_any_vehicle",
    "build_model",
    "FitOptions",
    "identify",
    "predict",
    "WindowProblem",
    "SampleOptions",
    "sample_tracks",
    "DiagnoseOptions",
    "diagnose",
    "DiscoveryOptions",
    "discover",
    "Runner",
}


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    return out.stdout


def test_all_lists_the_names_a_study_needs():
    assert set(bayesid.__all__) == EXPECTED
    assert len(bayesid.__all__) == len(set(bayesid.__all__))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_name_resolves_to_the_object_its_module_defines(name):
    obj = getattr(bayesid, name)
    assert obj.__name__ == name  # the object itself under its own name, not an alias
    assert getattr(importlib.import_module(obj.__module__), name) is obj
    assert obj.__module__.startswith("bayesid.")


def test_dir_lists_every_name_before_and_after_its_import():
    listed = json.loads(_run("import bayesid, json; print(json.dumps(dir(bayesid)))"))
    assert set(bayesid.__all__) | {"__version__"} <= set(listed)
    assert set(bayesid.__all__) <= set(dir(bayesid))


def test_a_renamed_name_still_resolves_with_a_deprecation_warning():
    with pytest.warns(DeprecationWarning, match="bayesid.FitProblem is now bayesid.WindowProblem"):
        old = bayesid.FitProblem
    assert old is bayesid.WindowProblem
    assert "FitProblem" not in bayesid.__all__


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="'identifi'"):
        bayesid.identifi  # noqa: B018
    assert not hasattr(bayesid, "load_vehicle")  # the loader of both families is load_any_vehicle


def test_import_bayesid_imports_no_submodule_and_no_numba():
    """The models' modules compile numba kernels; ``import bayesid`` loads none of them, and a
    name loads its own module only."""
    code = (
        "import sys, json, bayesid\n"
        "first = sorted(m for m in sys.modules if m.startswith(('bayesid.', 'numba')))\n"
        "bayesid.Track\n"
        "then = sorted(m for m in sys.modules if m.startswith(('bayesid.', 'numba')))\n"
        "print(json.dumps([first, then]))\n"
    )
    first, then = json.loads(_run(code))
    assert first == []
    assert "bayesid.data.track" in then
    assert not any(m.startswith(("bayesid.models", "bayesid.estimation", "bayesid.analysis", "numba")) for m in then)


def facade_imports(root: Path) -> list[str]:
    """``file:line name`` of every import of a public name from the package itself
    (``from bayesid import identify``, ``from .. import identify``) by a module under ``root/bayesid``."""
    bad = []
    for f in sorted((root / "bayesid").rglob("*.py")):
        pkg = list(f.relative_to(root).parts[:-1])  # where a relative import starts (a module's or an __init__'s)
        for node in ast.walk(ast.parse(f.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                mod = pkg[: len(pkg) - (node.level - 1)] + (node.module.split(".") if node.module else [])
            else:
                mod = node.module.split(".") if node.module else []
            if mod == ["bayesid"]:
                bad += [f"{f.relative_to(root)}:{node.lineno} {a.name}" for a in node.names if a.name in EXPECTED]
    return bad


def test_no_module_of_the_package_imports_the_public_names_from_the_package():
    """Inside the package a name comes from the module that defines it: ``from .. import
    diagnose`` in a lower layer would run up the layers past tests/test_layout.py's check."""
    assert not facade_imports(ROOT), facade_imports(ROOT)


def test_the_facade_import_finder_finds_them(tmp_path):
    (tmp_path / "bayesid" / "estimation").mkdir(parents=True)
    (tmp_path / "bayesid" / "estimation" / "x.py").write_text(
        "from .. import tasks\n\ndef f():\n    from .. import diagnose\n"
    )
    (tmp_path / "bayesid" / "y.py").write_text("from bayesid import __version__, Runner\n")
    assert facade_imports(tmp_path) == ["bayesid/estimation/x.py:4 diagnose", "bayesid/y.py:1 Runner"]


# --- diagnose() leaves out the effects the tracks cannot inform -----------------------------
@pytest.fixture(scope="module")
def ship_runs():
    """KVLCC2 model: two short zigzags (no wind columns)."""
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, service_condition, simulate_trial

    kv = bayesid.load_any_vehicle("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, service_condition(kv)["speed"])
    options = TrialOptions(dt=0.2, duration=60.0)
    runs = [simulate_trial(kv, "zigzag", a, speed=speed, rpm=rpm, options=options).track for a in (-10.0, 20.0)]
    return kv, runs


def _with_wind(track):
    data = dict(track.data, wind_speed=0 * track.t + 2.0, wind_dir=0 * track.t)
    return bayesid.Track(track.t, data, name=track.name, meta=track.meta)


def test_diagnose_leaves_out_a_catalogue_effect_whose_columns_the_tracks_lack(ship_runs):
    kv, (a, b) = ship_runs
    said = []
    options = bayesid.DiagnoseOptions(window_s=30.0, max_nfev=1, max_effects=1)
    d = bayesid.diagnose(kv, ["Nr"], [a], [b], options, runner=bayesid.Runner(progress=said.append))
    catalogue = list(bayesid.build_model(kv).CATALOGUE)
    assert "wind" in catalogue
    assert d.settings["candidates"] == [c for c in catalogue if c != "wind"]
    assert "wind" not in {r["effect"] for r in d.ranking}
    assert "no wind_speed, wind_dir columns in every track: the wind candidate is left out" in said


def test_the_catalogue_keeps_an_effect_every_track_has_the_columns_of(ship_runs):
    from bayesid.analysis.gap.diagnose import catalogue_candidates
    from bayesid.models import model_class

    kv, (a, b) = ship_runs
    family, said = model_class(kv), []
    assert "wind" in catalogue_candidates(family, [_with_wind(a), _with_wind(b)], bayesid.Runner(progress=said.append))
    assert not said
    # one track without the columns is enough to leave it out
    assert "wind" not in catalogue_candidates(family, [_with_wind(a), b])


def test_a_candidate_named_by_the_caller_is_kept(ship_runs):
    """Only the whole catalogue (``candidates=None``) is filtered: a named candidate is the caller's."""
    kv, (a, b) = ship_runs
    options = bayesid.DiagnoseOptions(candidates=("wind",), window_s=30.0, max_nfev=1, max_effects=1)
    assert bayesid.diagnose(kv, ["Nr"], [a], [b], options).settings["candidates"] == ["wind"]


def test_the_command_leaves_the_same_effects_out_and_says_so_once(ship_runs, tmp_path, capsys):
    from bayesid.cli import main

    kv, runs = ship_runs
    files = []
    for tr in runs:
        files.append(tmp_path / f"{tr.name}.csv")
        bayesid.write_csv(tr, files[-1])
    base = ["diagnose", "--vehicle", "kvlcc2_7m", "--free", "Nr", "--train", str(files[0]), "--heldout", str(files[1])]
    base += ["--score-window", "30", "--max-nfev", "1", "--max-effects", "1", "--no-discover"]
    said = "no wind_speed, wind_dir columns in every track: the wind candidate is left out"
    catalogue = list(bayesid.build_model(kv).CATALOGUE)
    for extra, left_out in (([], {"wind"}), (["--exclude", "delay"], {"wind", "delay"})):
        out = tmp_path / f"d{len(extra)}"
        assert main([*base, *extra, "--out", str(out)]) == 0
        assert capsys.readouterr().out.count(f"  {said}\n") == 1
        got = json.loads((out / "diagnosis.json").read_text())["settings"]["candidates"]
        assert got == [c for c in catalogue if c not in left_out]
    # excluding an effect the columns already left out is said and skipped: what was asked for holds
    assert main([*base, "--exclude", "wind", "--out", str(tmp_path / "dw")]) == 0
    assert "--exclude wind: already left out (said above)" in capsys.readouterr().out
    got = json.loads((tmp_path / "dw" / "diagnosis.json").read_text())["settings"]["candidates"]
    assert got == [c for c in catalogue if c != "wind"]
    # a name of no effect in the catalogue is refused, naming it (exit 2)
    assert main([*base, "--exclude", "wnid", "--out", str(tmp_path / "dx")]) == 2
    assert "--exclude wnid: not among the candidates" in capsys.readouterr().err
    # so is one left out of the caller's own --candidates
    assert main([*base, "--candidates", "delay", "--exclude", "wind", "--out", str(tmp_path / "dy")]) == 2
    assert "--exclude wind: not among the candidates ['delay']" in capsys.readouterr().err

"""Stale numba caches are dropped (bayesid._numba.drop_stale_caches): numba checks a cached function
against its own file only, so a caller cached in one model module keeps an old callee or constant of
another (seen: ship.trials._run kept the ship kernel's old parameter layout through ship.dynamics)."""

from __future__ import annotations

from bayesid import _numba


def _tree(tmp_path):
    root = tmp_path / "models"
    (root / "ship").mkdir(parents=True)
    (root / "__init__.py").write_text("A = 1\n")
    (root / "ship" / "__init__.py").write_text("B = 2\n")
    return root


def _fake_caches(root):
    files = []
    for d in (root / "__pycache__", root / "ship" / "__pycache__"):
        d.mkdir(exist_ok=True)
        for name in ("dynamics.rhs-1.py311.nbi", "dynamics.rhs-1.py311.1.nbc"):
            (d / name).write_bytes(b"x")
            files.append(d / name)
    (root / "__pycache__" / "other.cpython-311.pyc").write_bytes(b"keep")
    return files


def test_a_cache_built_from_other_sources_is_emptied_once_and_stamped(tmp_path):
    root = _tree(tmp_path)
    files = _fake_caches(root)
    _numba.sources_digest.cache_clear()
    dropped = _numba.drop_stale_caches(root)
    assert sorted(dropped) == sorted({f.parent for f in files})
    assert not any(f.exists() for f in files) and (root / "__pycache__" / "other.cpython-311.pyc").exists()
    digest = _numba.sources_digest(root)
    assert (root / "ship" / "__pycache__" / _numba.STAMP).read_text().strip() == digest
    # built from these sources (stamped): kept
    files = _fake_caches(root)
    assert _numba.drop_stale_caches(root) == [] and all(f.exists() for f in files)
    # a source of another module changes: every cache of the tree goes (a caller elsewhere may have
    # compiled it in)
    (root / "ship" / "__init__.py").write_text("B = 3\n")
    _numba.sources_digest.cache_clear()
    assert _numba.sources_digest(root) != digest
    assert len(_numba.drop_stale_caches(root)) == 2 and not any(f.exists() for f in files)
    _numba.sources_digest.cache_clear()


def test_the_package_caches_are_stamped_with_its_sources():
    import bayesid.models  # noqa: F401 - its import checks the stamps

    _numba.sources_digest.cache_clear()
    d = _numba.numba_cache_dir(_numba.Path(_numba.__file__).parent / "models" / "ship" / "dynamics.py")
    if d is None:  # numba's locators moved: nothing to check (and nothing dropped)
        return
    assert (d / _numba.STAMP).read_text().strip() == _numba.sources_digest()

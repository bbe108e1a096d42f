"""The licence and citation files agree with pyproject.toml (issue 38)."""

import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _project():
    with open(ROOT / "pyproject.toml", "rb") as fh:
        return tomllib.load(fh)["project"]


def test_license_file_is_the_licence_pyproject_names():
    text = (ROOT / "LICENSE").read_text()
    assert _project()["license"]["text"] == "MIT"
    assert text.startswith("MIT License")
    assert "Permission is hereby granted, free of charge" in text


def test_citation_version_licence_and_references():
    cff = (ROOT / "CITATION.cff").read_text()
    assert re.search(r"^cff-version: 1\.2\.0$", cff, re.M)
    version = re.search(r'^version: "?([^"\n]+)"?$', cff, re.M)
    assert version and version.group(1) == _project()["version"]
    assert re.search(r"^license: MIT$", cff, re.M)
    assert "10.1007/s00773-014-0293-y" in cff  # Yasukawa & Yoshimura 2015
    assert "Furlong" in cff and "Guidance and Control of Underwater Vehicles" in cff


def test_citation_is_valid_yaml_with_required_keys():
    yaml = pytest.importorskip("yaml")
    doc = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    for key in ("cff-version", "message", "title", "authors", "version", "license", "references"):
        assert key in doc, key
    assert all("title" in r and "authors" in r and "type" in r for r in doc["references"])

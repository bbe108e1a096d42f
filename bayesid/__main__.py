"""``python -m bayesid``: the ``bayesid`` command (:mod:`bayesid.cli`)."""

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())

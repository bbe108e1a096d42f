"""``python -m bayesid.cli``: the ``bayesid`` command."""

import sys

from . import main

sys.exit(main())

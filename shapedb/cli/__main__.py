"""``python -m shapedb.cli``: the same as the ``shapedb`` command."""

from __future__ import annotations

import sys

from shapedb.cli import main

sys.exit(main())

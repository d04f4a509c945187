"""``python -m query.cli``: the same as the ``shapedb`` command."""

from __future__ import annotations

import sys

from query.cli import main

sys.exit(main())

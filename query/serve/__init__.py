"""``shapedb serve``: a web page and a JSON API over one store, in one warm process.

FastAPI and uvicorn are imported only when a server is created (the ``serve`` extra).
"""

from __future__ import annotations

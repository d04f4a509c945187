"""``shapedb serve``: a web page and a JSON API over a store, in one warm process."""

from __future__ import annotations

import argparse
import os

from query.cli.common import add_db_argument, existing_store

__all__ = ["serve_arguments", "serve", "TOKEN_VARIABLE"]

#: Where ``--token`` is read from when it is not given (a command line is visible to ``ps``).
TOKEN_VARIABLE = "SHAPEDB_TOKEN"


def serve_arguments(s: argparse.ArgumentParser) -> None:
    """The arguments of ``serve``."""
    add_db_argument(s)
    s.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to bind (default 127.0.0.1; any other needs a token)",
    )
    s.add_argument("--port", type=int, default=8000, help="TCP port (default 8000; 0: any free)")
    s.add_argument(
        "--token",
        metavar="TOKEN",
        help=f"bearer token for uploads, ingest and SQL (default: ${TOKEN_VARIABLE})",
    )
    s.add_argument(
        "--max-upload-mb", type=float, default=64.0, metavar="MB", help="largest upload (64)"
    )


def serve(args: argparse.Namespace) -> int:
    """``shapedb serve --db DIR``: serve until interrupted."""
    from query.serve.server import serve as serve_database

    db = existing_store(args.db)
    token = args.token or os.environ.get(TOKEN_VARIABLE) or None

    def ready(url: str) -> None:
        print(f"serving {args.db} ({len(db)} shapes) at {url}  (Ctrl-C to stop)", flush=True)

    serve_database(
        db,
        host=args.host,
        port=args.port,
        token=token,
        max_upload_bytes=int(args.max_upload_mb * 2**20),
        on_ready=ready,
    )
    return 0

"""The `metairl` command: serve, worker, keys, demo (README, "Command line"; the names and flags are a contract).

Each subcommand imports its implementation lazily so `metairl keys` never loads torch or Celery.
"""

from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    """Parse the command line and run the chosen subcommand; returns the process exit code."""
    parser = argparse.ArgumentParser(
        prog="metairl", description="Meta inverse reinforcement learning service."
    )
    sub = parser.add_subparsers(dest="command", required=True)

    serve = sub.add_parser(
        "serve", help="start the API and one worker on the configured (default: embedded) stores"
    )
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    serve.add_argument(
        "--workers",
        type=int,
        default=None,
        help="API processes (default: one per core this process may use)",
    )

    worker = sub.add_parser("worker", help="start a Celery worker alone")
    worker.add_argument(
        "--concurrency", type=int, default=1, help="jobs run at once (each uses all its threads)"
    )

    keys = sub.add_parser("keys", help="manage API keys")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True)
    create = keys_sub.add_parser("create", help="create a lab (if new) and print a new API key for it")
    create.add_argument("--lab", required=True, help="lab name; resources belong to the lab")
    listing = keys_sub.add_parser(
        "list", help="one key per line: id, lab, created, last used, revoked (tab-separated)"
    )
    listing.add_argument("--lab", default=None, help="only this lab's keys")
    revoke = keys_sub.add_parser("revoke", help="revoke a key: the next request with it gets 401")
    revoke.add_argument("key_id", metavar="KEY_ID", help="the key's id (as listed), or the whole key")

    demo = sub.add_parser("demo", help="run the paper's terrain experiment against a running service")
    demo.add_argument("--url", default="http://127.0.0.1:8000")
    demo.add_argument("--api-key", default=None, help="default: create one in the local database")
    demo.add_argument("--out", default="demo-out")
    demo.add_argument("--quick", action="store_true", help="a one-minute version")

    args = parser.parse_args(argv)
    if args.command == "serve":
        from metairl_cli.serve import serve as run_serve

        return run_serve(host=args.host, port=args.port, workers=args.workers)
    if args.command == "worker":
        from worker.main import run_worker

        return run_worker(concurrency=args.concurrency)
    if args.command == "keys":
        from metairl_cli import keys as keys_cli

        if args.keys_command == "list":
            return keys_cli.list_keys_command(lab=args.lab)
        if args.keys_command == "revoke":
            return keys_cli.revoke_key_command(key_id=args.key_id)
        return keys_cli.create_key_command(lab=args.lab)
    if args.command == "demo":
        from metairl_cli.demo import run_demo

        return run_demo(url=args.url, api_key=args.api_key, out=args.out, quick=args.quick)
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())

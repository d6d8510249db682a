"""The `metairl` command: serve, worker, keys, demo (API.md "Command line and settings").

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

    worker = sub.add_parser("worker", help="start a Celery worker alone")
    worker.add_argument(
        "--concurrency", type=int, default=1, help="jobs run at once (each uses all its threads)"
    )

    keys = sub.add_parser("keys", help="manage API keys")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True)
    create = keys_sub.add_parser("create", help="create a lab (if new) and print a new API key for it")
    create.add_argument("--lab", required=True, help="lab name; resources belong to the lab")

    demo = sub.add_parser("demo", help="run the paper's terrain experiment against a running service")
    demo.add_argument("--url", default="http://127.0.0.1:8000")
    demo.add_argument("--api-key", default=None, help="default: create one in the local database")
    demo.add_argument("--out", default="demo-out")
    demo.add_argument("--quick", action="store_true", help="a one-minute version")

    args = parser.parse_args(argv)
    if args.command == "serve":
        from service.serve import serve as run_serve

        return run_serve(host=args.host, port=args.port)
    if args.command == "worker":
        from worker.main import run_worker

        return run_worker(concurrency=args.concurrency)
    if args.command == "keys":
        from service.keys import create_key_command

        return create_key_command(lab=args.lab)
    if args.command == "demo":
        from service.demo import run_demo

        return run_demo(url=args.url, api_key=args.api_key, out=args.out, quick=args.quick)
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())

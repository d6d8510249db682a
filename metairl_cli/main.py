"""The `metairl` command: serve, worker, keys, demo (README, "Command line"; the names and flags are a contract).

Each subcommand imports its implementation lazily so `metairl keys` never loads torch or Celery.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import PackageNotFoundError, version

EXAMPLES = {
    "metairl": """examples:
  metairl serve                          # API and a worker on ./var, prints the URL and a key last
  metairl keys create --lab motion-lab   # a key for another lab
  metairl demo --quick                   # the paper's terrain experiment against the running service
  metairl SUBCOMMAND --help              # each subcommand's options and examples""",
    "serve": """examples:
  metairl serve                              # http://127.0.0.1:8000, data in ./var
  METAIRL_DATA_DIR=~/metairl metairl serve   # data (SQLite file, broker, key) kept elsewhere
  metairl serve --host 0.0.0.0 --port 9000   # reachable from other machines
  metairl serve --access-log                 # log every request (off by default)

The local lab's key is kept in METAIRL_DATA_DIR/local-api-key and printed again at each start.""",
    "worker": """examples:
  metairl worker                    # one job at a time, on the configured database and broker
  metairl worker --concurrency 2    # two jobs at once (torch threads are split between them)
  metairl worker --name second@%h   # a second worker on this host, under a node name of its own
  METAIRL_BROKER_URL=redis://127.0.0.1:6379/0 metairl worker""",
    "keys": """examples:
  metairl keys create --lab motion-lab   # prints a new key alone on the last line
  metairl keys list --lab motion-lab     # id, lab, created, last used, revoked
  metairl keys revoke 85039365110284c6   # by the id `keys list` shows: the next request gets 401""",
    "keys create": """examples:
  metairl keys create --lab motion-lab                            # prints the new key alone on the last line
  KEY=$(metairl keys create --lab motion-lab | tail -n 1)         # the key alone, for a script
  METAIRL_DATA_DIR=~/metairl metairl keys create --lab gait-lab   # for the service kept there

The key is stored hashed and shown only this once; a lab may hold several keys.""",
    "keys list": """examples:
  metairl keys list                              # every lab's keys: id, lab, created, last used, revoked
  metairl keys list --lab motion-lab             # one lab's (exit 1 if it has none)
  metairl keys list | awk -F '\\t' '$5 == "-"'    # the keys still active""",
    "keys revoke": """examples:
  metairl keys revoke 85039365110284c6   # by the id `keys list` shows: the next request gets 401
  metairl keys revoke "$KEY"             # or by the whole key""",
    "demo": """examples:
  metairl demo --quick                   # under a minute, with the key `metairl serve` keeps
  metairl demo --out results             # the full experiment; figure, heatmaps and tables in results/
  METAIRL_API_KEY=mirl_… metairl demo --url http://lab-server:8000

Without --api-key or METAIRL_API_KEY the demo uses the key `metairl serve` keeps in METAIRL_DATA_DIR; run it
with the same METAIRL_DATA_DIR as the service (it never creates a database).""",
}
"""The examples under each command's help."""


def metairl_version() -> str:
    """The installed metairl's version ("unknown" when run from a checkout that was never installed)."""
    try:
        return version("metairl")
    except PackageNotFoundError:
        return "unknown"


def command_parser(
    sub: argparse._SubParsersAction[argparse.ArgumentParser], name: str, help: str, *, within: str = ""
) -> argparse.ArgumentParser:
    """A subcommand (of command ``within``, if given: ``keys``) whose help ends with its examples."""
    return sub.add_parser(
        name,
        help=help,
        description=help[0].upper() + help[1:] + ".",
        epilog=EXAMPLES[f"{within} {name}".strip()],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def build_parser() -> argparse.ArgumentParser:
    """The whole command line."""
    parser = argparse.ArgumentParser(
        prog="metairl",
        description="Meta inverse reinforcement learning service.",
        epilog=EXAMPLES["metairl"],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"metairl {metairl_version()}")
    sub = parser.add_subparsers(dest="command", required=True)

    serve = command_parser(
        sub, "serve", "start the API and one worker on the configured (default: embedded) stores"
    )
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (default: %(default)s)")
    serve.add_argument("--port", type=int, default=8000, help="port to listen on (default: %(default)s)")
    serve.add_argument(
        "--workers",
        type=int,
        default=None,
        help="API processes (default: one per core this process may use)",
    )
    serve.add_argument(
        "--access-log", action="store_true", help="log one line per HTTP request (default: off)"
    )

    worker = command_parser(sub, "worker", "start a Celery worker alone")
    worker.add_argument(
        "--concurrency",
        type=int,
        default=None,
        help="jobs run at once, each with its share of the cores (default: METAIRL_WORKER_CONCURRENCY, else 1)",
    )
    worker.add_argument(
        "--quiet",
        action="store_true",
        help="no Celery start-up banner nor INFO lines (warnings and errors only); 'celery@HOST ready.' once ready",
    )
    worker.add_argument(
        "--name",
        default=None,
        help="the worker's Celery node name (default celery@HOST; %%h is the host name): a second worker on one "
        "host needs its own, as RabbitMQ lets one worker of a name consume its control queue",
    )

    keys = command_parser(sub, "keys", "manage API keys")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True)
    create = command_parser(
        keys_sub, "create", "create a lab (if new) and print a new API key for it", within="keys"
    )
    create.add_argument("--lab", required=True, help="lab name; resources belong to the lab")
    listing = command_parser(
        keys_sub,
        "list",
        "one key per line: id, lab, created, last used, revoked (tab-separated)",
        within="keys",
    )
    listing.add_argument("--lab", default=None, help="only this lab's keys")
    revoke = command_parser(
        keys_sub, "revoke", "revoke a key: the next request with it gets 401", within="keys"
    )
    revoke.add_argument("key_id", metavar="KEY_ID", help="the key's id (as listed), or the whole key")

    demo = command_parser(sub, "demo", "run the paper's terrain experiment against a running service")
    demo.add_argument("--url", default="http://127.0.0.1:8000", help="the service (default: %(default)s)")
    demo.add_argument(
        "--api-key", default=None, help="default: $METAIRL_API_KEY, else the key `metairl serve` keeps"
    )
    demo.add_argument("--out", default="demo-out", help="folder for the results (default: %(default)s)")
    demo.add_argument("--quick", action="store_true", help="18 small jobs, under a minute")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse the command line and run the chosen subcommand; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "serve":
        from metairl_cli.serve import serve as run_serve

        return run_serve(host=args.host, port=args.port, workers=args.workers, access_log=args.access_log)
    if args.command == "worker":
        from worker.main import run_worker

        return run_worker(concurrency=args.concurrency, quiet=args.quiet, name=args.name)
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

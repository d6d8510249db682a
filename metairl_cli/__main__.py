"""``python -m metairl_cli`` runs the `metairl` command."""

import sys

from metairl_cli.main import main

sys.exit(main())

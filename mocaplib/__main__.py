"""``python -m mocaplib`` runs the command line (Ctrl-C while it loads: exit 130, quietly)."""

import sys

try:
    from .cli import main
except KeyboardInterrupt:
    sys.exit(130)

sys.exit(main())

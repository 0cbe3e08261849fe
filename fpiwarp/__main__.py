"""``python -m fpiwarp``: the same as the ``fpiwarp`` command."""

import sys

from .cli.commands import main

if __name__ == "__main__":
    sys.exit(main())

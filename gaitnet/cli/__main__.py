"""``python -m gaitnet.cli``: the ``gaitnet`` command."""

import sys

from gaitnet.cli import main

sys.exit(main())

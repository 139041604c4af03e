"""``python -m app`` is the ``backlash`` command."""

import sys

from app.cli import main

sys.exit(main())

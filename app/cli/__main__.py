"""``python -m app.cli`` is the ``backlash`` command."""

import sys

from app.cli.main import main

sys.exit(main())

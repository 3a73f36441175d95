"""`python -m dynid ...`: the command line, as `dynid ...` (where the script is not on PATH, or for one Python)."""

import sys

from .cli.main import main

sys.exit(main())

import sys

from geometry.common import run_cli

from .cli import main

sys.exit(run_cli(main, None, prog="python -m impact"))

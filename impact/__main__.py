"""``python -m impact``: signal handling first, then the heavy imports of :mod:`impact.cli`."""

import sys

from rpud_common.launch import launch

sys.exit(launch("impact.cli", prog="python -m impact"))

"""``python -m linkage_monitor.cli``: the ``linkage-monitor`` command."""

import sys

from linkage_monitor.cli.main import main

sys.exit(main())

"""``python -m hubbeam_ctrl ...``: the ``hubbeam`` command (as ``python -m hubbeam_ctrl.cli``)."""

import sys

from hubbeam_ctrl.cli import main

sys.exit(main())

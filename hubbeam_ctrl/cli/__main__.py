import sys

from hubbeam_ctrl.cli.main import main

sys.exit(main())

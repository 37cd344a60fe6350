"""`python -m mca_drake.app.cli`: the `mca-drake` command."""

import sys

from mca_drake.app.cli import main

sys.exit(main())

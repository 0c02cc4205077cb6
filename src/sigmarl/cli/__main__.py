"""`python -m sigmarl.cli`: the command line."""

import sys

from sigmarl.cli import main

sys.exit(main())

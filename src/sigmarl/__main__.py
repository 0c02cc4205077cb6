"""`python -m sigmarl ...`, the same as the `sigmarl` command."""

import sys

from sigmarl.cli import main

sys.exit(main())

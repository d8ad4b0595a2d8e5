"""`python -m mlct.cli ...` (as under torchrun): the `mlct` command."""

import sys

from mlct.cli import main

sys.exit(main())

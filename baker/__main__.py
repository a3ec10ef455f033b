"""`python -m baker`: the same as the `baker` command."""

import sys

from baker.entry import main

sys.exit(main())

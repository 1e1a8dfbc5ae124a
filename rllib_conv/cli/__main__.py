"""`python -m rllib_conv.cli`: the same as the `rllib-conv` command."""

import sys

from rllib_conv.cli import main

sys.exit(main())

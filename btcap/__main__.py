"""``python -m btcap``: the same as the ``btcap`` console script."""

import sys

from btcap.cli import main

sys.exit(main())

"""Moved to :mod:`btcap.team.protocol`; this path re-exports it for one release."""

import warnings

from btcap.team.protocol import *  # noqa: F403
from btcap.team.protocol import __all__ as __all__

warnings.warn(
    "btcap.protocol moved to btcap.team.protocol; import it from there",
    DeprecationWarning,
    stacklevel=2,
)

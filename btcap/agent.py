"""Moved to :mod:`btcap.team.agent`; this path re-exports it for one release."""

import warnings

from btcap.team.agent import *  # noqa: F403
from btcap.team.agent import __all__ as __all__

warnings.warn(
    "btcap.agent moved to btcap.team.agent; import it from there",
    DeprecationWarning,
    stacklevel=2,
)

"""Moved to :mod:`btcap.team.capfiles`; this path re-exports it for one release."""

import warnings

from btcap.team.capfiles import *  # noqa: F403
from btcap.team.capfiles import __all__ as __all__

warnings.warn(
    "btcap.capfiles moved to btcap.team.capfiles; import it from there",
    DeprecationWarning,
    stacklevel=2,
)

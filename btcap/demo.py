"""Moved to :mod:`btcap.team.demo`; this path re-exports it for one release."""

import warnings

from btcap.team.demo import *  # noqa: F403
from btcap.team.demo import __all__ as __all__

warnings.warn(
    "btcap.demo moved to btcap.team.demo; import it from there",
    DeprecationWarning,
    stacklevel=2,
)

"""Physics submodels of the semi-active damper (thesis chapter 4).

Numba's cache folder is a hash of every compiled source
(dampertwin.numba_cache), set before the submodels below are decorated.
"""

from ..numba_cache import cache_sources, configure as _configure_cache  # noqa: F401 (cache_sources: re-exported)

_configure_cache()

# Load the submodels in layout's declared order: a direct first import of one of
# them (e.g. `import dampertwin.model.params`, as the docs hook does) would
# otherwise meet the chambers -> layout -> bench cycle half-initialised.
from . import layout as _layout  # noqa: E402,F401

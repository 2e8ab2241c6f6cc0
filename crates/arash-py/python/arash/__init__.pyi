from ._arash import BaseParameters as BaseParameters, Robot as Robot, __version__ as __version__

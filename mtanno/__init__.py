"""mtanno: find, retrieve and annotate human motions in motion-capture archives.

The package reads the pipeline left to right: :mod:`mtanno.io` (mocap files to joint
positions), :mod:`mtanno.features` (40 boolean relational features at 30 Hz) and
:mod:`mtanno.store` (Parquet feature files). The command line (:mod:`mtanno.cli`) is a
thin layer over these functions.
"""

from mtanno.errors import MtannoError

__version__ = "0.1.0"

__all__ = ["MtannoError", "__version__"]

"""Device models, one module per PSS/E dyr model, each a group vectorized over its
devices (see `base`)."""

from .gencls import GENCLS as GENCLS

"""ftnav's version: a leaf module, so every writer that stamps its files imports it
without importing the package's top level (which loads the pipeline on first use)."""

__version__ = "0.1.0"

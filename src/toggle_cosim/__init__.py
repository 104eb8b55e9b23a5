"""toggle-cosim: the Fung, Wu and Chen (2001) PMLSM toggle mechanism as an FMU plus a VSC master."""

__version__ = "0.1.0"

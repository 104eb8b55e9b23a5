"""`python -m toggle_cosim ...`: the same as the `toggle-cosim` script."""

from toggle_cosim.cli import main

main()

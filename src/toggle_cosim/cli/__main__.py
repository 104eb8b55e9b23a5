"""`python -m toggle_cosim.cli ...`: the same as the `toggle-cosim` script."""

from toggle_cosim.cli import main

main()

"""``python -m glider_cosim.cli``: the ``glider-cosim`` console script."""

from .main import console_main

if __name__ == "__main__":
    console_main()

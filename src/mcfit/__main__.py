"""``python -m mcfit``."""

from mcfit.cli import main

if __name__ == "__main__":
    main()

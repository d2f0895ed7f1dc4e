"""Entry point for ``python -m fem_runout``."""

from fem_runout.cli import main

if __name__ == "__main__":
    raise SystemExit(main())

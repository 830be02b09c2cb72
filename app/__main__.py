"""`python -m granstab_app`: the same as `granstab-app`."""
from .server import main

if __name__ == "__main__":
    raise SystemExit(main())

import sys

try:
    from .cli import main
except KeyboardInterrupt:          # Ctrl-C while the modules load: one line, as main() says it later
    print("granstab: interrupted (Ctrl-C) while starting; nothing was done", file=sys.stderr)
    sys.exit(130)

sys.exit(main())

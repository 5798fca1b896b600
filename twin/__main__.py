"""`python -m twin` and the `twin` console script: the command, with a Ctrl-C while its libraries
still load ending in one line, as a Ctrl-C does later (twin.cli.app.main), not in a traceback."""
import sys


def main() -> None:
    try:
        from .cli import main as run  # late: a Ctrl-C while it loads ends in one line (below), not a traceback
    except KeyboardInterrupt:
        sys.stderr.write("aborted\n")
        sys.exit(130)
    run()


if __name__ == "__main__":
    main()

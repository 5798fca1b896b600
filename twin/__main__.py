"""`python -m twin` runs the `twin` command."""
from .cli import main

main()

"""``python -m kronsub``."""
from .cli import main

main()

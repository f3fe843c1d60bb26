"""`python -m urident` runs the same CLI as the `urident` console script."""
from urident.cli.main import console

console()

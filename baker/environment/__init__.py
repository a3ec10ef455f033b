"""Environment loading and ray queries. The only package (besides export/) that touches files,
and it only reads them."""

from baker.environment.load import load_environment
from baker.environment.model import EnvMesh, Environment, Sun

__all__ = ["EnvMesh", "Environment", "Sun", "load_environment"]

"""geoddp: Differential Dynamic Programming on Lie groups over Pinocchio."""
from .result import Result

__all__ = ["Result"]
__version__ = "0.1.0"

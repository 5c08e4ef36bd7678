"""optik: optimization-based inverse kinematics for robot arms."""

from optik.errors import OptikError
from optik.model import DHJoint, Joint, Mimic, Robot

__version__ = "0.1.0"

__all__ = ["DHJoint", "Joint", "Mimic", "OptikError", "Robot", "__version__"]

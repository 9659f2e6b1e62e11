"""Errors of the kinematics core."""


class Unreachable(ValueError):
    """No valid joint solution: out of reach, beyond joint limits, or singular.

    A ValueError subclass, so callers that refuse bad input catch both; the
    message says which and by how much.
    """

"""The paper's recovery problem, defined once: owns its numbers (``spec``: envelope, reset bounds, targets,
step, altitude, recovery tolerances, each cited), the observation/action spaces and their mapping
(``spaces``), the recovery criterion, envelope and outcome codes (``criteria``), the initial conditions and
the open-loop spin scenario (``scenarios``) and the spin bank (``spin_bank``).

``control/``, ``env/``, ``evaluation/`` and the training metrics import these names; ``task`` itself
imports only ``aircraft``, ``dynamics`` and ``units``.
"""

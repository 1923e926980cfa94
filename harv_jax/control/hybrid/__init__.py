"""The hybrid controller u = u_RL + zeta u_SMC: its law (``law``), settings (``settings``), zeta schedules
(``schedules``, the tube laws in ``zeta``, the certificate gate in ``gate``), the safety filter (``safety``)
and the fallback supervisor (``supervisor``)."""

"""The paper's recovery problem, defined once: envelope, reset bounds, targets, step and altitude.

``spec`` holds the numbers (each cited); the observation/action mapping and the recovery criterion and
outcome codes live beside it. ``control/``, ``env/``, ``evaluation/`` and the training recipe import these
names; nothing here imports them.
"""

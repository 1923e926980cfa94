"""Every seed of a training run judged (``harv-jax evaluate``): the conditions and their cells
(``conditions``), the order of the work (``flow``), the acceptance criteria (``acceptance``) and the report
(``report``)."""

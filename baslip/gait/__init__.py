"""One gait: the multiple-shooting NLP, the Newton polish, the independent verification,
stability, and the result record; solved from a problem by
:mod:`baslip.gait.from_problem`."""

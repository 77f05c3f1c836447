"""Drawing only: figures of studies, branches and gaits, and animations. Takes rows and
sampled motions; imports nothing above :mod:`baslip.engine`."""

"""Problem files: reading untrusted YAML, numbers with units, and every check of a problem
and its study section, into frozen dataclasses. Imports nothing above
:mod:`baslip.model`."""

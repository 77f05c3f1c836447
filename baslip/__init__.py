"""baslip: periodic running gaits of the Body-Attached SLIP and their stability."""

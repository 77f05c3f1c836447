"""``results/REPORT.md``: the thesis's claims of chapter 4 beside what baslip finds
(``python -m baslip.report``)."""

"""Benchmarks: ``python -m ocdsl.bench`` (core stages), ``ocdsl bench FILES`` (ocdsl against a
generated CasADi script). Nothing here is imported at run time by the rest of ocdsl, and
CasADi's Python module is only ever imported by the generated scripts (ocdsl loads only its Ipopt library)."""

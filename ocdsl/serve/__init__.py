"""``ocdsl serve``: a process with ocdsl's modules loaded that runs commands in forks of itself.

A small ``ocdsl run`` spends most of its CPU importing SymPy, Pyomo, pydantic and NumPy
(reports/bench/peers_idle.md: 0.7-0.9 s of a 1.0 s double-integrator run). With a server
started (``ocdsl serve start``), the console script hands its command line, working folder,
environment and standard streams to the server, which forks a worker per command: the
worker starts from the loaded modules and nothing else (every command gets a fresh copy of
the server, never what an earlier command left), runs the command exactly as the console
script would, and sends back its exit code.

* ``address``: where a server listens, named by a fingerprint of the code it loaded;
* ``client``: the console script's side (standard library only, so it starts in
  milliseconds);
* ``server``: loading, listening and the workers.
"""

"""How a render is judged against Cycles: per-pass error maps and rMAE (``metrics``, ``compare``), temporal error of
sequences (``temporal``), time-against-error curves (``convergence``) and whole scenes subdivided for scaling runs
(``subdivision``). May import ``core``; nothing of the engine imports it."""

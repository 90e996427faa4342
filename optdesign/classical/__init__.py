"""Classical layer: analytical references (Riccati solvers, the sequential Solheim/Chang-Lee
method, the closed forms of the seed papers, block-pulse Riccati DE, pole placement)."""

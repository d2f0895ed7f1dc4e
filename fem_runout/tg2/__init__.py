"""TG2-PC: two-step Taylor–Galerkin with path-conservative edges and FCT (seed §3.1)."""

"""Pure numerics: friction models as vectorised functions of numpy arrays with named parameters."""

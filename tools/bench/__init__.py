"""tools.bench: one benchmark command for hyfc (docs/performance.md)."""

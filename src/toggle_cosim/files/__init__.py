"""Reading and writing files: bounded reads, the one YAML loader, traces."""

"""Built-in scenarios as YAML files (package data)."""

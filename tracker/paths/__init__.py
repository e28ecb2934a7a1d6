"""Reference paths and speed profiles: built-in shapes, ISO 3888-1 gates, circuits from CSV."""

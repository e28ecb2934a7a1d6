"""The MCAP log: writing, schemas, Foxglove messages, reading back and export."""

"""The base layer every part shares: records, configuration fields, parameters, errors,
YAML, compiled functions and plug-in loading."""

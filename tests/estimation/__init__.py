"""Tests of the state estimators (estimation/)."""

"""Sensorless cable-failure detection and identification, safe points and recovery planning."""

"""The digital twin (healthy rigid model with its own controller) and the plant simulator with failure injection."""

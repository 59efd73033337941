"""Built-in o3dheat filters."""

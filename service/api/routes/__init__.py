"""HTTP routes, one module per resource: thin layers that call the data functions and commit."""

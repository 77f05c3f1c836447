"""Built-in model descriptions: the SLIP and the one-legged hopper of the guide."""

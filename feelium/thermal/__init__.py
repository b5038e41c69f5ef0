"""MLX90640 thermal camera: I2C transport, decoder, simulated sensor (sim), presence detector."""

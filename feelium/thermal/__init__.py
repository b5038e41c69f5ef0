"""MLX90640 thermal camera: I2C transport, decoder, emulator, presence detector."""

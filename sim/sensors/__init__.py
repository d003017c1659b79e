"""The sensor error models: gyros, accelerometers, UHFO, temperature laws, noise, anomalies, pulse counting, the IMU."""

"""Device interfaces and backends (serial DAQ, Modbus amplifier, simulated)."""

"""floe's domain vocabulary, shared by every layer: the local frame and its geodesy, and
ArduPlane's flight modes. No I/O, no clock; imports nothing of floe's."""

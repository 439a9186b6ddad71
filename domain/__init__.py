"""floe's domain vocabulary, shared by every layer: the local frame and its geodesy,
ArduPlane's flight modes, the error tree, the documented input limits, and the input checking
every reader of a user's file shares (the safe YAML reader and its field helpers, the
fault-spec grammar). No clock; its only I/O is reading a user's YAML file
(``yaml_fields.load_yaml_file``). It imports nothing of floe's outside ``domain``."""

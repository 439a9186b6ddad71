"""The world floe's vehicles fly in: scenarios, the true icebergs, the boat and the camera,
and the UAV's planar dynamics. Used by the MAVLink simulator (``sitl``), the offline runner
(``gcs simulate``) and the daemon's scenario truth; it imports only ``domain`` of floe's
packages (its YAML reader and the fault grammar among them)."""

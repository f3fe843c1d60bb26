"""The RTDE wire protocol (TCP 30004), shared by the simulated controller (server side) and the
session's recorder (client side). No ur_rtde here: this is our own codec of UR's documented
message format."""

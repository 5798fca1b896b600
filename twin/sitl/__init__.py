"""The twin as ArduPilot SITL's physics backend over its JSON interface (`twin sitl`).

protocol.py  the bytes: servo packets in, JSON state lines out (pure functions)
backend.py   SitlTwin: the vessel's twin stepped one frame at a time, recorded as a Run
server.py    the UDP loop (lock-step or real time) and `run_sitl`, which the CLI calls
params.py    the ArduPilot parameter file for a vessel (`twin sitl --write-params`)
ardupilot.py ArduPilot Rover SITL started and flown over MAVLink (`twin mission`, the tests)

docs/method/sitl.md states what crosses the link; docs/guide/10-autopilot.md flies a mission.
"""

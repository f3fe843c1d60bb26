"""Simulated Universal Robots controller that the unmodified ur_rtde 1.6.5 client connects to.

Run it as its own process (ur_rtde's Python constructors hold the GIL)::

    urident sim-controller --robot ur5e --host 127.0.0.2 [--fault protective_stop@2.5] [--effects FILE]
    python -m urident.simcontroller ...          # same options

or from Python with :class:`urident.simcontroller.process.SimControllerProcess`.

Modules, one concept each:

* :mod:`urident.rtde.protocol` - RTDE framing, value types, recipe packing (port 30004)
* :mod:`.fields`        - RTDE output/input names, types and the versions that have them
* :mod:`.snapshot`      - one cycle's output values by field name
* :mod:`.dashboard`     - dashboard replies (port 29999)
* :mod:`.script_emulator` - emulation of ur_rtde's control script (register handshake)
* :mod:`.plant`         - joint motion, torques (TorqueModel + effect hooks), currents, temperatures
* :mod:`.kinematics`    - DH forward kinematics for the TCP fields
* :mod:`.faults`        - ``--fault`` specs and their schedule
* :mod:`.robot_state`   - robot/safety/runtime codes, registers, I/O
* :mod:`.controller`    - the per-cycle state machine tying these together
* :mod:`.server`        - sockets, connection threads and the paced real-time loop
* :mod:`.launch`        - command-line options; :mod:`.process` - the child-process helper
"""

"""Certification: the ceiling of a scene, start by start.

* :mod:`~agents.certification.certify`: plan and replay every start with the planner
  the scene's objective calls for; returns the certificate and its action records;
* :mod:`~agents.certification.search`: the certifying planners' passes over the starts;
* :mod:`~agents.certification.replays`: the replay every record passes (its start's
  stated outcome, and its drawn parameters under randomised physics);
* :mod:`~agents.certification.witnesses`: any policy's action record that replays to the
  scene's success makes an open start feasible (witnesses, sampled draws);
* :mod:`~agents.certification.warm_start`: the iLQR planner taking over a policy's
  trajectory part of the way (goal scenes).

A certificate is written and read as the typed record
:class:`agents.artifacts.certificates.Certificate`, its records beside it
(:class:`agents.artifacts.certificates.Certified`).
"""

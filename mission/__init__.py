"""UAV-based RF source localization (RFSL).

Data flow, one module per step: mission spec (``spec``) -> trajectory (``trajectory``) -> flight
(``flight``) or simulation (``simulate``) -> log (``flightlog``) -> features (``localize.features``)
-> localizer (``localize``) -> report.  Radio physics lives in ``physics``; geodesy and areas in
``geo``.
"""

__version__ = "0.1.0"

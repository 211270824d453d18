"""fc.control: the robust coordinated attitude law of Mu, Wang, Wu, Ying (Trans. NUAA 2018).

A pure numeric library (no sockets, clocks, logging or MAVLink): ``law.AttitudeLaw`` over the
numba kernels of ``kernels``, the parameter table ``params.LAW_PARAMS``, the array layouts
(``layout``, including the estimated-state layout ``E_*``) and the controller's own nominal
model (``nominal`` + ``data/nominal_model.npz``). The equation-by-equation map is
docs/control_law.md. Modules are imported explicitly (``from fc.control.law import
AttitudeLaw``) so that importing the layout does not load numba code.
"""

"""The tyre's parameters: a record of the plant's configuration (``plant.tyre``).

The force code that uses them is :mod:`cosim.plant.tyre_model`; the record lives here, below
the plant, because :class:`cosim.core.vehicle_params.PlantConfig` embeds it and the controllers
read ``vehicle_params`` without importing the plant.
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim.core.config_fields import setting
from cosim.core.exceptions import ConfigError


@dataclass(frozen=True)
class TyreParams:
    """One tyre: Magic Formula coefficients (Pacejka 2012 notation) and carcass properties.

    Defaults: the book's 205/60R15 passenger-car tyre (Pacejka 2006, Appendix 3, Table A3.1;
    the MF 6.1 reference tyre, nominal load 4000 N), magnitudes of the ISO-sign table, shifts
    and camber terms dropped, with an isotropic friction circle (the peak is ``mu F_z`` in
    both directions; the table has ``mu_x`` 1.21, ``mu_y`` 0.99, which the friction scales
    ``lambda_mux``, ``lambda_muy`` can state: 1.21 and 0.99 with friction 1). Carcass
    stiffnesses set the relaxation lengths at nominal load to about a wheel radius laterally
    (Pacejka's rule of thumb) and 0.2 m longitudinally; see models/README.md.
    """

    nominal_load_n: float = setting(4000.0, low=100.0, high=1e5, doc="F_z0")
    # Longitudinal, pure slip.
    longitudinal_shape: float = setting(1.685, low=1.01, high=1.99, doc="C_x = p_Cx1")
    longitudinal_curvature: float = setting(0.344, low=-10.0, high=1.0, doc="E_x = p_Ex1")
    slip_stiffness_per_load: float = setting(
        21.51, low=1.0, high=100.0, doc="p_Kx1: K_xk / F_z at F_z0 [-]"
    )
    slip_stiffness_load_slope: float = setting(-0.163, low=-10.0, high=10.0, doc="p_Kx2")
    slip_stiffness_load_exponent: float = setting(0.245, low=-10.0, high=10.0, doc="p_Kx3")
    peak_friction_load_slope: float = setting(
        0.0,
        low=-0.9,
        high=0.9,
        doc="p_D2 = p_Dx2 / p_Dx1 (and the same laterally): the peak friction "
        "mu (1 + p_D2 df_z) falls with load when negative (Pacejka 2012, 4.E13, 4.E23); "
        "0: load-independent, as before this key",
    )
    longitudinal_friction_scale: float = setting(
        1.0,
        low=0.1,
        high=3.0,
        doc="lambda_mux: the longitudinal peak friction over plant.tyre_friction, mu_x = "
        "lambda_mux tyre_friction (Pacejka 2012, 4.E13); 1: isotropic",
    )
    lateral_friction_scale: float = setting(
        1.0,
        low=0.1,
        high=3.0,
        doc="lambda_muy: the lateral peak friction over plant.tyre_friction, mu_y = "
        "lambda_muy tyre_friction (4.E23); 1: isotropic",
    )
    # Lateral, pure slip.
    lateral_shape: float = setting(1.193, low=1.01, high=1.99, doc="C_y = p_Cy1")
    lateral_curvature: float = setting(-1.003, low=-10.0, high=1.0, doc="E_y = p_Ey1")
    cornering_stiffness_max_prad: float = setting(
        14.95, low=1.0, high=100.0, doc="p_Ky1: max of K_ya / F_z0 [1/rad]"
    )
    cornering_stiffness_peak_load_ratio: float = setting(
        2.130, low=0.1, high=10.0, doc="p_Ky2: load of max K_ya / F_z0"
    )
    # Combined slip.
    combined_x_stiffness: float = setting(12.35, low=0.0, high=100.0, doc="r_Bx1")
    combined_x_stiffness_decay: float = setting(-10.77, low=-100.0, high=100.0, doc="r_Bx2")
    combined_x_shape: float = setting(1.092, low=0.0, high=1.99, doc="r_Cx1")
    combined_y_stiffness: float = setting(6.461, low=0.0, high=100.0, doc="r_By1")
    combined_y_stiffness_decay: float = setting(4.196, low=-100.0, high=100.0, doc="r_By2")
    combined_y_shape: float = setting(1.081, low=0.0, high=1.99, doc="r_Cy1")
    # Carcass (transient response and standstill).
    longitudinal_carcass_stiffness_npm: float = setting(
        4.5e5, low=1e3, high=1e8, doc="c_x: sigma_k = K_xk / c_x"
    )
    lateral_carcass_stiffness_npm: float = setting(
        1.6e5, low=1e3, high=1e8, doc="c_y: sigma_a = K_ya / c_y"
    )
    longitudinal_carcass_damping_nspm: float = setting(
        100.0, low=1.0, high=1e5, doc="d_x, at every speed"
    )
    lateral_carcass_damping_nspm: float = setting(
        100.0, low=1.0, high=1e5, doc="d_y, at every speed"
    )
    low_speed_longitudinal_damping_nspm: float = setting(
        1500.0, low=0.0, high=1e5, doc="added to d_x at standstill, faded out by V_low"
    )
    low_speed_lateral_damping_nspm: float = setting(
        5000.0, low=0.0, high=1e6, doc="added to d_y at standstill, faded out by V_low"
    )
    low_speed_damping_fade_mps: float = setting(
        2.5, low=0.01, high=20.0, doc="V_low: the low-speed damping is zero above it"
    )
    slip_speed_floor_mps: float = setting(
        0.1, low=1e-3, high=5.0, doc="v_N in v* = sqrt(V_cx^2 + v_N^2)"
    )

    def __post_init__(self) -> None:
        # Shape factors C in (1, 2): the curve reaches its peak mu F_z and keeps the sign
        # of the slip (the bounds of the fields).
        if self.slip_stiffness_per_load + self.slip_stiffness_load_slope * -1.0 <= 0.0:
            raise ConfigError(
                f"tyre.slip_stiffness_load_slope = {self.slip_stiffness_load_slope}: the slip "
                "stiffness must stay positive down to zero load"
            )

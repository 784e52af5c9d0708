"""Plots of a ``Trajectory`` with matplotlib.

Every function returns a ``matplotlib.figure.Figure`` built without ``pyplot`` (no global state,
no GUI; saving uses the Agg renderer), so it works headless, in scripts and in notebooks. The
quantities are the columns of ``results.csv`` (see ``jaxclear.io.result_columns``), e.g.
``"slider_x"``, ``"slider_a"``, ``"crank_torque"``, ``"A_Fx"``, ``"constraint_violation"``.

Each plotting function takes an optional ``reference`` trajectory (for instance the ideal-joint run)
drawn first, thin and grey, behind the main curve::

    ideal = jaxclear.simulate(jaxclear.mechanisms.slider_crank(), t1)
    fig = plot_vs_crank_angle(clearance_run, "slider_a", reference=ideal)
    fig.savefig("slider_acceleration.png")
"""

from ._chaos import plot_bifurcation as plot_bifurcation
from ._chaos import plot_lyapunov_sweep as plot_lyapunov_sweep
from ._common import BODY_LABELS as BODY_LABELS
from ._common import DPI as DPI
from ._common import ENSEMBLE_FAILED_STYLE as ENSEMBLE_FAILED_STYLE
from ._common import FIGSIZE as FIGSIZE
from ._common import QUANTITY_LABELS as QUANTITY_LABELS
from ._common import SWEEP_LOG_RATIO as SWEEP_LOG_RATIO
from ._common import UNIT_LABELS as UNIT_LABELS
from ._common import parameter_axis as parameter_axis
from ._common import save_figure as save_figure
from ._ensembles import COMBINATION_MIN_SHARE as COMBINATION_MIN_SHARE
from ._ensembles import MODE_COLOURS as MODE_COLOURS
from ._ensembles import main_ensemble_statistics as main_ensemble_statistics
from ._ensembles import plot_ensemble_histograms as plot_ensemble_histograms
from ._ensembles import plot_ensemble_scatter as plot_ensemble_scatter
from ._ensembles import plot_sweep as plot_sweep
from ._ensembles import plot_sweep_modes as plot_sweep_modes
from ._ensembles import save_ensemble_plots as save_ensemble_plots
from ._ensembles import statistic_axis as statistic_axis
from ._fit import plot_fit as plot_fit
from ._fit import plot_loss as plot_loss
from ._fit import save_fit_plots as save_fit_plots
from ._runs import MAIN_STYLE as MAIN_STYLE
from ._runs import MODE_STYLE as MODE_STYLE
from ._runs import REFERENCE_STYLE as REFERENCE_STYLE
from ._runs import STANDARD_PLOTS as STANDARD_PLOTS
from ._runs import lubricated_joint_names as lubricated_joint_names
from ._runs import plot_constraint_violation as plot_constraint_violation
from ._runs import plot_contact_forces as plot_contact_forces
from ._runs import plot_eccentricity_orbit as plot_eccentricity_orbit
from ._runs import plot_film_forces as plot_film_forces
from ._runs import plot_joint_forces as plot_joint_forces
from ._runs import plot_mode_timeline as plot_mode_timeline
from ._runs import plot_orbit as plot_orbit
from ._runs import plot_vs_crank_angle as plot_vs_crank_angle
from ._runs import plot_vs_time as plot_vs_time
from ._runs import save_mode_timeline as save_mode_timeline
from ._runs import save_standard_plots as save_standard_plots
from ._runs import standard_plots as standard_plots
from ._translational import plot_corner_forces as plot_corner_forces
from ._translational import plot_corner_gaps as plot_corner_gaps
from ._translational import plot_slider_tilt as plot_slider_tilt
from ._translational import save_translational_plots as save_translational_plots

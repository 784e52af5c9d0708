"""Input and output: measured records, output columns and result files (csv, npz, json)."""

from ._columns import Column as Column
from ._columns import clearance_joint_names as clearance_joint_names
from ._columns import column_map as column_map
from ._columns import column_summary as column_summary
from ._columns import mode_shares as mode_shares
from ._columns import result_columns as result_columns
from ._columns import run_statistics as run_statistics
from ._files import CSV_FORMAT as CSV_FORMAT
from ._files import CSV_NAME as CSV_NAME
from ._files import NPZ_NAME as NPZ_NAME
from ._files import RUN_FORMAT as RUN_FORMAT
from ._files import RUN_JSON_NAME as RUN_JSON_NAME
from ._files import atomic_write as atomic_write
from ._files import package_versions as package_versions
from ._files import write_csv as write_csv
from ._files import write_json as write_json
from ._files import write_modes_csv as write_modes_csv
from ._files import write_npz as write_npz
from ._files import write_results as write_results
from ._files import write_revolutions_csv as write_revolutions_csv
from ._measurements import Measurements as Measurements
from ._measurements import estimate_noise as estimate_noise

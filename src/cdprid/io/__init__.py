"""Dataset input/output: the spec-v1 reader, aligner and writer, trajectory CSV files, and
importers of other formats."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.io._align import AlignedSignals as AlignedSignals
from cdprid.io._align import align as align
from cdprid.io._align import sampling_report as sampling_report
from cdprid.io._c3d import import_c3d as import_c3d
from cdprid.io._caspr import CasprImport as CasprImport
from cdprid.io._caspr import read_caspr as read_caspr
from cdprid.io._dataset import DATASET_FILES as DATASET_FILES
from cdprid.io._dataset import Dataset as Dataset
from cdprid.io._dataset import DatasetError as DatasetError
from cdprid.io._dataset import dataset_inputs as dataset_inputs
from cdprid.io._dataset import read_csv_stream as read_csv_stream
from cdprid.io._dataset import read_dataset as read_dataset
from cdprid.io._drives import DriveData as DriveData
from cdprid.io._drives import drive_table as drive_table
from cdprid.io._drives import read_drives as read_drives
from cdprid.io._drives import read_stream as read_stream
from cdprid.io._mat import write_mat as write_mat
from cdprid.io._rosbag import import_rosbag as import_rosbag
from cdprid.io._rosbag import list_topics as list_topics
from cdprid.io._rosbag import write_rosbag as write_rosbag
from cdprid.io._table import import_table as import_table
from cdprid.io._trajectory import load_trajectory_csv as load_trajectory_csv
from cdprid.io._trajectory import save_trajectory_csv as save_trajectory_csv
from cdprid.io._uacdpr import DEFAULT_SWIVEL_AXIS as DEFAULT_SWIVEL_AXIS
from cdprid.io._uacdpr import import_uacdpr as import_uacdpr
from cdprid.io._uacdpr import load_uacdpr as load_uacdpr
from cdprid.io._uacdpr import sources_of as sources_of
from cdprid.io._uacdpr import uacdpr_meta as uacdpr_meta
from cdprid.io._uacdpr import write_uacdpr as write_uacdpr
from cdprid.io._writer import robot_toml as robot_toml
from cdprid.io._writer import write_dataset as write_dataset

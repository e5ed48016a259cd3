"""Dataset input/output: the spec-v1 reader, aligner and writer, trajectory CSV files, and
importers of other formats."""

from cdprid.io.align import AlignedSignals as AlignedSignals
from cdprid.io.align import align as align
from cdprid.io.align import sampling_report as sampling_report
from cdprid.io.dataset import Dataset as Dataset
from cdprid.io.dataset import DatasetError as DatasetError
from cdprid.io.dataset import read_dataset as read_dataset
from cdprid.io.trajectory import load_trajectory_csv as load_trajectory_csv
from cdprid.io.trajectory import save_trajectory_csv as save_trajectory_csv
from cdprid.io.writer import write_dataset as write_dataset

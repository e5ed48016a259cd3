"""Dataset input/output: the spec-v1 reader and writer, and importers of other formats."""

from .dataset import (
    AlignedSignals as AlignedSignals,
    Dataset as Dataset,
    DatasetError as DatasetError,
    align as align,
    read_dataset as read_dataset,
    sampling_report as sampling_report,
    write_dataset as write_dataset,
)

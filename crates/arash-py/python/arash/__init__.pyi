from ._arash import (
    BaseParameters as BaseParameters,
    Excitation as Excitation,
    Identification as Identification,
    Robot as Robot,
    __version__ as __version__,
    butter as butter,
    consistent_least_squares as consistent_least_squares,
    design_excitation as design_excitation,
    filtfilt as filtfilt,
    identify as identify,
    load_model as load_model,
    paper_validation_trajectory as paper_validation_trajectory,
)

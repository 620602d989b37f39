"""Dataset folders over the measured data in ../shared/datasets, read in place (never copied)."""

from pathlib import Path


def piezo_dataset(shared: Path, folder: Path) -> Path:
    src = shared / "piezo_sindy_1hz" / "hysteresis_v_150_1hz.csv"
    folder.mkdir()
    (folder / "dataset.toml").write_text(f'''name = "piezo-sindy-1hz"
description = "piezo actuator, 150 V 1 Hz sine (Chandra et al. 2023), read in place"
time_column = "t"
input_column = "u"
output_column = "y"
input_unit = "V"
output_unit = "um"
csv_columns = ["index", "t", "y", "u"]

[[records]]
file = "{src}"
frequency_hz = 1.0
role = "identification"
''')
    return folder


def pzt_dataset(shared: Path, folder: Path) -> Path:
    src = shared / "pzt_ceramic_aixacct"
    folder.mkdir()
    files = {0.01: "tri_T02_TEST_0.01Hz_1400V_0.01Hz.csv", 0.1: "tri_T01_TEST_0.1Hz_1400V_0.1Hz.csv",
             1.0: "tri_T06_TEST_1400V_1400V_1Hz.csv"}
    roles = {0.01: "identification", 0.1: "validation", 1.0: "identification"}
    recs = "".join(f'\n[[records]]\nfile = "{src / f}"\nfrequency_hz = {fr}\nrole = "{roles[fr]}"\n'
                   for fr, f in files.items())
    (folder / "dataset.toml").write_text(
        'name = "pzt-ceramic"\ntime_column = "t_s"\ninput_column = "V_V"\noutput_column = "P_uC_per_cm2"\n'
        'input_unit = "V"\noutput_unit = "uC/cm2"\n' + recs)
    return folder

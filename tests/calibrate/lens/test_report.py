"""A calibration for a person: the paper's Fig. 8 drawn and written."""


def test_plot_draws_profiles_onsets_and_model(paper_sphere, tmp_path):
    fig = paper_sphere.plot()
    ax = fig.axes[1]
    assert len(ax.lines) >= 4 and "ratio to f/8" in ax.get_ylabel()
    paper_sphere.save_plot(tmp_path / "fig8.png")
    assert (tmp_path / "fig8.png").read_bytes()[:4] == b"\x89PNG"

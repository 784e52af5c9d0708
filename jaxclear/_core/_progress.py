"""Progress bars of long studies (tqdm)."""


def progress_bar(on: bool, total: int, description: str):
    """A tqdm bar over ``total`` evaluations (disabled, so updates cost nothing, when not ``on``)."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=description, unit="solve", disable=not on)

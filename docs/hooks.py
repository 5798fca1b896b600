"""MkDocs hooks: pages made from the code at build time (the command reference from the typer
app), so the site cannot drift from what the package does."""


def on_page_markdown(markdown, page, **kwargs):
    if "<!-- cli-reference -->" in markdown:
        from twin.cli.reference import markdown as cli_markdown

        markdown = markdown.replace("<!-- cli-reference -->", cli_markdown())
    return markdown

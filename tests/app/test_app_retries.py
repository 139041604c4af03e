"""Service hardening (issue 51), items 4 and 5: idempotent retries, and a job's result stored with its state.

4. A retry is idempotent: retrying one job twice (at once, or again later) runs the work once, and a retry of a
   training whose set is already stored finishes at once instead of failing with ``PatternSetExists``.
5. The result (a pattern set, a diagnosis's result) and the job's move to ``done`` are one transaction: a
   service killed between the two writes stores neither, and the retry after the restart succeeds.

Real servers (``backlash serve`` in a subprocess). The kill of item 5 happens inside the worker process that
runs the job, at the moment it moves the job to ``done``: a ``sitecustomize`` module the test writes (loaded by
every interpreter the server starts, through ``PYTHONPATH``) wraps :meth:`JobRepository.finish` so that it kills
the service and then its own process, as a power cut would. Nothing in the service knows of it.
"""

from __future__ import annotations

import os
import signal
import sqlite3
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import pytest
from servicekit import FAILING_TRAINING, SMALL_TRAINING, Server, ServerFactory, train, wait_for_job
from test_app_diagnoses import record_in, submit

from app.db.jobs import JobRepository, JobState
from engine.storage import PatternStore

#: Loaded at the start of every interpreter of the test's servers (see the module docstring).
KILLER = '''
"""A worker process that moves a job of the kind $KILL_WHEN_FINISHING to done kills its service, then itself."""
import os
import signal

_KIND = os.environ.get("KILL_WHEN_FINISHING")
if _KIND:
    import multiprocessing

    from app.db import jobs as _jobs

    _finish = _jobs.JobRepository.finish

    def _finish_or_die(self, job_id, **kwargs):
        job = self.get(job_id)
        if multiprocessing.parent_process() is not None and job is not None and job.kind == _KIND:
            os.kill(os.getppid(), signal.SIGKILL)  # the service (the worker's parent) ...
            os.kill(os.getpid(), signal.SIGKILL)  # ... and this worker, before the job is done
        return _finish(self, job_id, **kwargs)

    _jobs.JobRepository.finish = _finish_or_die
'''


def killed_when_finishing(
    kind: str, start_server: ServerFactory, db: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> Server:
    """A server on ``db`` whose worker processes kill it when they move a job of ``kind`` to done."""
    inject = tmp_path / "inject"
    inject.mkdir(exist_ok=True)
    (inject / "sitecustomize.py").write_text(KILLER)
    paths = [str(inject), *filter(None, [os.environ.get("PYTHONPATH")])]
    with monkeypatch.context() as env:  # the servers copy the test's environment when they start
        env.setenv("PYTHONPATH", os.pathsep.join(paths))
        env.setenv("KILL_WHEN_FINISHING", kind)
        return start_server(db_path=db)


def wait_killed(server: Server) -> None:
    assert server.proc is not None
    assert server.proc.wait(timeout=120) == -signal.SIGKILL, server.log()


def rows(db: Path, sql: str, *args: Any) -> list[tuple[Any, ...]]:
    """Rows of a query on the database file, read directly (no service in between)."""
    with sqlite3.connect(db) as conn:
        return conn.execute(sql, args).fetchall()


def retry_at_once(client: httpx.Client, job_id: str, n: int) -> list[httpx.Response]:
    """``n`` POST /v1/jobs/{id}/retry sent together."""
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(lambda _: client.post(f"/v1/jobs/{job_id}/retry"), range(n)))


# -- 5. the result and the job's state in one transaction -------------------------------------------------


@pytest.mark.slow  # 47 s: three services, a training and a diagnosis
def test_a_kill_between_storing_the_result_and_finishing_the_job_stores_neither(
    start_server: ServerFactory, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 51, item 5: a service killed when a training's set (then a diagnosis's result) is written and its job
    is about to move to done stores neither; after the restart the job is interrupted, and its retry (4: two at
    once) runs once and stores the result."""
    db = tmp_path / "service.sqlite3"
    server = killed_when_finishing("train_pattern_set", start_server, db, tmp_path, monkeypatch)
    with server.client() as c:
        training = c.post("/v1/pattern-sets", json=SMALL_TRAINING)
        assert training.status_code == 202, training.text
    wait_killed(server)
    set_id, training_job = training.json()["pattern_set_id"], training.json()["job_id"]
    assert rows(db, "SELECT state FROM jobs WHERE id = ?", training_job) == [("running",)]
    assert rows(db, "SELECT id FROM pattern_sets WHERE id = ?", set_id) == []  # neither: no set without its job

    server = killed_when_finishing("diagnose", start_server, db, tmp_path, monkeypatch)
    with server.client() as c:
        diagnosis = submit(c, record_in(c, asset="press-51"))
    wait_killed(server)
    diagnosis_job = diagnosis["job_id"]
    assert rows(db, "SELECT state FROM jobs WHERE id = ?", diagnosis_job) == [("running",)]
    assert rows(db, "SELECT status, result_z IS NULL FROM diagnoses WHERE id = ?", diagnosis["diagnosis_id"]) == [
        (None, 1)
    ]
    assert rows(db, "SELECT count(*) FROM figures WHERE owner_id = ?", diagnosis["diagnosis_id"]) == [(0,)]

    server = start_server(db_path=db)
    with server.client() as c:
        for job_id in (training_job, diagnosis_job):
            job = c.get(f"/v1/jobs/{job_id}").json()
            assert job["state"] == "interrupted" and "retry" in job["error"], job
        assert c.get(f"/v1/pattern-sets/{set_id}").status_code == 404
        assert c.get(diagnosis["diagnosis_url"]).json()["state"] == "interrupted"

        retried = c.post(f"/v1/jobs/{training_job}/retry")
        assert retried.status_code == 202, retried.text
        done = wait_for_job(c, retried.json()["id"])
        assert (done["state"], done["pattern_set_id"], done["error"]) == ("done", set_id, None), done
        assert c.get(f"/v1/pattern-sets/{set_id}").status_code == 200

        answers = retry_at_once(c, diagnosis_job, 3)  # item 4: retried three times at once, run once
        assert sorted(r.status_code for r in answers) == [200, 200, 202], [r.text for r in answers]
        assert len({r.json()["id"] for r in answers}) == 1
        retry = answers[0].json()
        assert wait_for_job(c, retry["id"])["state"] == "done"
        d = c.get(diagnosis["diagnosis_url"]).json()
        assert (d["state"], d["job_id"]) == ("done", retry["id"]) and d["result"]["verdict"]
        assert [j["id"] for j in c.get("/v1/jobs", params={"kind": "diagnose"}).json()["items"]] == [
            retry["id"],
            diagnosis_job,
        ]


# -- 4. idempotent retries ----------------------------------------------------------------------------------


def test_retrying_a_diagnosis_twice_runs_it_once(client: httpx.Client) -> None:
    """Issue 51, item 4: two retries of one job sent together give one new job (202, then 200 with the same job);
    a retry asked again after it finished returns it (200) instead of running the diagnosis a third time."""
    accepted = submit(client, record_in(client, asset="press-52"))
    cancelled = client.post(f"{accepted['job_url']}/cancel")
    assert cancelled.status_code == 200 and cancelled.json()["state"] == "cancelled", cancelled.text

    answers = retry_at_once(client, accepted["job_id"], 2)
    assert sorted(r.status_code for r in answers) == [200, 202], [r.text for r in answers]
    first, second = (r.json() for r in answers)
    assert first["id"] == second["id"] and first["retry_of"] == accepted["job_id"]
    assert all(r.headers["location"] == f"/v1/jobs/{first['id']}" for r in answers)
    assert wait_for_job(client, first["id"])["state"] == "done"

    later = client.post(f"{accepted['job_url']}/retry")
    assert (later.status_code, later.json()["id"], later.json()["state"]) == (200, first["id"], "done"), later.text
    retries = [j for j in client.get("/v1/jobs", params={"kind": "diagnose"}).json()["items"] if j["retry_of"]]
    assert [j["id"] for j in retries if j["retry_of"] == accepted["job_id"]] == [first["id"]]
    own = client.post(f"/v1/jobs/{first['id']}/retry")  # a done job has nothing to retry
    assert own.status_code == 409 and "done" in own.json()["detail"], own.text


def test_a_training_retry_whose_set_is_already_stored_finishes_at_once(server: Server, client: httpx.Client) -> None:
    """Issue 51, item 4: a training job left interrupted after its set was stored (what a kill between the two
    writes left before item 5, and what such a file still holds) is retried without training: the retry is done at
    once with the same set, where it used to fail with ``PatternSetExists``."""
    trained = train(client)
    assert trained["job"]["state"] == "done", trained["job"]
    db = Path(server.env["BACKLASH_DB_PATH"])
    with sqlite3.connect(db) as conn:  # the state a kill between the two writes left
        conn.execute("UPDATE jobs SET state = 'interrupted', stage = 'interrupted' WHERE id = ?", (trained["job_id"],))

    retried = client.post(f"/v1/jobs/{trained['job_id']}/retry")
    assert retried.status_code == 202, retried.text
    done = wait_for_job(client, retried.json()["id"])
    assert (done["state"], done["pattern_set_id"], done["error"]) == ("done", trained["pattern_set_id"], None), done
    assert "already stored" in done["stage"]
    assert client.get(trained["pattern_set_url"]).status_code == 200
    again = client.post(f"/v1/jobs/{trained['job_id']}/retry")
    assert (again.status_code, again.json()["id"]) == (200, done["id"]), again.text


def test_a_retry_of_a_job_whose_retry_failed_retries_the_newest_of_the_chain(client: httpx.Client) -> None:
    """Issue 51, item 4: after a retry has failed too, retrying the first job re-runs the failed retry (``retry_of``
    names it), so that a job has at most one retry and the chain is a line."""
    r = client.post("/v1/pattern-sets", json=FAILING_TRAINING)
    assert r.status_code == 202, r.text
    first = r.json()["job_id"]
    assert wait_for_job(client, first)["state"] == "failed"
    second = client.post(f"/v1/jobs/{first}/retry").json()
    assert second["retry_of"] == first
    assert wait_for_job(client, second["id"])["state"] == "failed"
    third = client.post(f"/v1/jobs/{first}/retry")
    assert third.status_code == 202, third.text
    assert third.json()["retry_of"] == second["id"] and third.json()["id"] != second["id"]
    assert wait_for_job(client, third.json()["id"])["state"] == "failed"


def test_finish_job_stores_the_result_only_with_the_jobs_move_to_done(tmp_path: Path) -> None:
    """Issue 51, item 5, in process: :func:`finish_job` writes the result and moves the job in one transaction; a
    job no longer running (cancelled) stores nothing of it, and a write that fails leaves the job running."""
    from app.jobs.manager import JobResult, finish_job  # here: the module's other tests also run on older code

    store = PatternStore(tmp_path / "jobs.sqlite3")
    repo = JobRepository(store)

    def result(tag: str, fail: bool = False) -> JobResult:
        def write(conn: sqlite3.Connection) -> None:
            repo.create("result", meta={"tag": tag}, spec={}, conn=conn)  # any row of the file stands for a result
            if fail:
                raise RuntimeError("the disk is full")

        return JobResult({"tag": tag}, write)

    def written(tag: str) -> bool:
        return bool(repo.list(kind="result", tag=tag))

    ok, cancelled, failing = (repo.create("test", meta={}, spec={}) for _ in range(3))
    for job in (ok, cancelled, failing):
        assert repo.start(job.id)
    assert finish_job(repo, ok.id, result("ok"))
    assert written("ok") and repo.get(ok.id).state is JobState.done  # type: ignore[union-attr]

    assert repo.cancel(cancelled.id)
    assert not finish_job(repo, cancelled.id, result("cancelled"))
    assert not written("cancelled") and repo.get(cancelled.id).state is JobState.cancelled  # type: ignore[union-attr]

    with pytest.raises(RuntimeError, match="disk is full"):
        finish_job(repo, failing.id, result("failing", fail=True))
    assert not written("failing") and repo.get(failing.id).state is JobState.running  # type: ignore[union-attr]

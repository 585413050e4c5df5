//! The watched directory on PostgreSQL: folders taken out of order keep the newest orientation
//! (the conditional upsert of `watch_orientations` on this backend's SQL).

use crate::support;

use support::server::TestServer;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_folder_taken_late_leaves_the_newer_orientations_on_postgres() {
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("watch");
    let server = TestServer::start(move |c| c.database_url = Some(url)).await;
    assert_eq!(server.store.backend(), cliffwatch::store::Backend::Postgres);
    server.create_site("kamo").await;
    server.create_site("kura").await;
    let watch = tempfile::tempdir().unwrap();
    support::watch::folders_taken_out_of_order(&server.store, watch.path()).await;
    server.stop().await;
}
